"""Where the guided map leads a bvc robot (Wang et al. 2024, Sec. IV-C): the goal ``p_g`` and
the density ``phi = exp(-gamma M_go)`` of Eq. 8 at the samples of its buffered cell.

The goal is the highest-density point within sensing range that the robot can reach in what it
has seen and that lies in its own Voronoi region (:func:`.guided_map.local_maximum_goal`);
with ``seek_peaks``, a peak no robot attends (:mod:`.peaks`), reached round the teammates;
under a flat density, the middle of what its scans have seen free of its region.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies.base import Observation
from coverage_ros.core.strategies.bvc.cells import BufferedCell
from coverage_ros.core.strategies.bvc.guided_map import (
    WindowGraph,
    guided_density,
    local_map,
    local_maximum_goal,
    navigation_function,
    without_discs,
)
from coverage_ros.core.strategies.bvc.memory import ObstacleMemory, bridge_shadows
from coverage_ros.core.strategies.bvc.peaks import PeakRole, density_peaks, peak_role

#: The density over the guided map's candidates counts as flat (no goal to be guided to) when
#: its largest value is within this share of its smallest.
FLAT_DENSITY = 0.01


@dataclass(frozen=True)
class GuidedField:
    goal: np.ndarray  # (2,) [m] p_g
    cost: np.ndarray  # (N,) [m] M_go at the cell samples
    cost_here: float  # [m] M_go at the robot
    phi: np.ndarray  # (N,) Eq. 8 weights at the samples


class Guide:
    """One robot's guided map over its :class:`ObstacleMemory` (shared with the strategy,
    which adds the scans' hits): it keeps the last goal (for the goal's hysteresis) and the
    density's peaks (found at first use)."""

    def __init__(self, domain: CoverageDomain, memory: ObstacleMemory, radius: float,
                 sensor_radius: float, nf_radius: float, gamma: float, bridge_width: float,
                 seek_peaks: bool) -> None:
        self.domain = domain
        self.memory = memory
        self.radius = radius  # [m] the robot's
        self.sensor_radius = sensor_radius  # [m] R_sensor
        self.gamma = gamma  # [1/m] of Eq. 8
        self.bridge_width = bridge_width  # [m] see memory.bridge_shadows
        self.seek_peaks = seek_peaks
        self.nf_cells = int(math.ceil(nf_radius / memory.resolution))
        self.graph = WindowGraph(2 * self.nf_cells + 1, memory.resolution)
        self.goal: np.ndarray | None = None
        self._peaks: np.ndarray | None = None

    def field(self, p: np.ndarray, xy: np.ndarray, cell: BufferedCell, obs: Observation,
              team: tuple[np.ndarray, np.ndarray]) -> GuidedField | None:
        """Eq. 8 at the cell samples ``xy``, or None when no goal can be reached (the caller
        falls back to the importance density). ``team``: the neighbours' positions and
        radii."""
        local = local_map(self.memory, p, self.nf_cells, self.radius)
        nodes, cand = self._window(p, self.sensor_radius)
        # Candidates: inside the own (unbuffered) Voronoi region - the region this robot is
        # tasked with - and reachable in what it has seen. A robot heading for a peak nobody
        # attends goes where it is nearest that peak, round its neighbours: its bisector with
        # a neighbour between it and the peak would hold it behind that neighbour.
        role = self._peak_role(p, team[0])
        if role is not None and role.peakless:
            return None  # every peak kept or sought by others: cover round them (Lloyd)
        peak = None if role is None else role.target
        rp = cell.robot_planes
        own = np.all(cand @ rp.a.T <= rp.b[None, :], axis=1) if len(rp) and peak is None \
            else np.ones(len(cand), dtype=bool)
        if peak is not None:
            local = without_discs(local, team[0], team[1] + self.radius)
        domain = self.domain
        ok = own & local.is_reachable(cand) & domain.free.ravel()[nodes]
        if not ok.any():
            return None
        values = domain.density.ravel()[nodes[ok]]
        cand = cand[ok]
        k: int | None
        if peak is None and values.max() <= values.min() * (1.0 + FLAT_DENSITY):
            # No peak to be guided to (a uniform density): every candidate ties, and the
            # nearest - the robot's own spot - would hold the robot in place. Be guided to the
            # middle of what is its own instead: the candidate nearest to the centroid of the
            # part of its Voronoi region within sensing range that its scans have seen free -
            # not only the current scan, and with the shadows of narrow obstacles (pillars,
            # teammates) filled in: space hidden behind them would otherwise not pull the
            # robot, which then settles short of it, leaving that side thin. Without a map,
            # space never seen behind a wall must not pull it, and it does not: a wall's shadow
            # has no far side.
            scan, at = obs.scan, obs.scan_origin
            assert scan is not None  # (the strategy updates with a scan only)
            depths = bridge_shadows(scan.depths(), scan.angle_increment,
                                    self.bridge_width, scan.full_circle)
            self.memory.add_view(at[:2], self.sensor_radius, lambda q: scan.sees(q, at, depths))
            seen = self.memory.was_seen(cand)
            if seen.any():
                cand = cand[seen]
            k = int(np.argmin(np.hypot(*(cand - cand.mean(axis=0)).T)))
        else:
            if peak is not None:  # (closer to the peak is higher; the same hysteresis)
                values = np.exp(-np.hypot(*(cand - peak).T) / self.sensor_radius)
            k = local_maximum_goal(cand, values, p, self.goal, match_radius=domain.resolution)
        if k is None:
            return None
        self.goal = cand[k].copy()
        nf = navigation_function(local, self.goal, self.graph, origin=p,
                                 reach=self.sensor_radius)
        cost = nf.at(xy)
        phi = guided_density(cost, self.gamma)
        if phi.sum() <= 0:
            return None
        return GuidedField(self.goal.copy(), cost, float(nf.at(p)[0]), phi)

    def _window(self, p: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """Domain nodes ``(N,)`` within ``reach`` [m] of ``p`` and their centres ``(N, 2)``."""
        domain = self.domain
        H, W = domain.shape
        g = domain.to_grid(p)[0]
        n = int(math.ceil(reach / domain.resolution)) + 1
        c0, c1 = max(int(g[0]) - n, 0), min(int(g[0]) + n + 1, W)
        r0, r1 = max(int(g[1]) - n, 0), min(int(g[1]) + n + 1, H)
        if c0 >= c1 or r0 >= r1:
            return np.zeros(0, np.int64), np.zeros((0, 2))
        rows, cols = np.mgrid[r0:r1, c0:c1]
        nodes = (rows * W + cols).ravel()
        xy = domain.to_map(domain.node_centers(nodes))
        near = np.hypot(*(xy - p).T) <= reach
        return nodes[near], xy[near]

    def _peak_role(self, p: np.ndarray, nb: np.ndarray) -> PeakRole | None:
        """This robot's role among the density's peaks (:mod:`.peaks`); None without
        ``seek_peaks`` or peaks."""
        if not self.seek_peaks:
            return None
        if self._peaks is None:
            self._peaks = density_peaks(self.domain, self.sensor_radius)
        return peak_role(p, self._peaks, nb, self.sensor_radius) if len(self._peaks) else None
