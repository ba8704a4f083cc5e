"""The last word on every velocity command of a disc robot (:class:`SafetyFilter`).

The unicycle arc of (v, w) over the stopping horizon is simulated against the configuration
space (walls), the neighbours' discs and the lidar points, and v is cut (to zero if need be;
turning in place is always allowed for a disc robot) until the arc is clear. No command ever
drives into a wall.

A neighbour is checked where it is, and - when it publishes its velocity - also where it will
be along the arc's times if it keeps that velocity; either check can cut v. Checked only where
it is, two robots driving side by side on slowly converging headings each saw the other fall
behind their own arc, and touched (the live Lee & Lee Fig. 17a-c: 0.3 m apart at 0.4 m/s, 4
degrees apart, closing at 3 cm/s).

Poses are ``(x, y, yaw)`` in the map frame [m, rad].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.control.planning import CHECK_STEP_CELLS
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies.base import Scan
from coverage_ros.core.world.robot import RobotSpec

#: v scales tried by the safety filter, largest first (0 is always safe).
SAFE_SCALES = (1.0, 0.6, 0.3, 0.12, 0.0)
#: [m] lidar points kept around the robot across scans (:class:`ScanMemory`): beyond the
#: filter's reach (stopping arc + radius + 0.2 m, at most ~0.46 m for a TurtleBot3).
MEMORY_RADIUS = 0.5
#: [m] kept points closer together than this count once.
MEMORY_CELL = 0.01
#: Key of a memory cell (column * stride + row): unique for cells within 2^31 cells (21,000 km)
#: of the origin.
_KEY_STRIDE = 1 << 32


@dataclass(frozen=True)
class SafetyConfig:
    radius: float = RobotSpec().radius  # [m] own body
    robot_margin: float = 0.06  # [m] kept free between two robots' bodies
    # [m] kept free to lidar points. Small on purpose: walls are already kept at the
    # configuration space's clearance (measured between cell centres, which lets a path pass a
    # real wall edge ~1 cm closer than radius + 3 cm); the scan check is for what the map lacks.
    obstacle_margin: float = 0.01
    horizon: float = 0.6  # [s] arc simulated beyond the stopping distance
    a_max: float = RobotSpec().a_max  # [m/s^2] braking

    def clearance_to(self, radii: np.ndarray) -> np.ndarray:
        """[m] centre to centre distance kept from neighbours of ``radii``."""
        return self.radius + np.asarray(radii, dtype=np.float64) + self.robot_margin


def unicycle(pose: np.ndarray, v: float, w: float, t: np.ndarray) -> np.ndarray:
    """``(len(t), 3)`` poses of a differential drive holding ``(v, w)`` from ``pose`` for
    each time in ``t`` [s] (an arc, or a straight line when ``w`` is 0)."""
    t = np.asarray(t, dtype=np.float64)
    yaw = pose[2] + w * t
    if abs(w) < 1e-6:
        x = pose[0] + v * t * math.cos(pose[2])
        y = pose[1] + v * t * math.sin(pose[2])
    else:
        x = pose[0] + v / w * (np.sin(yaw) - math.sin(pose[2]))
        y = pose[1] - v / w * (np.cos(yaw) - math.cos(pose[2]))
    return np.stack([x, y, yaw], axis=-1)


class ScanMemory:
    """The lidar points near the robot, kept across scans in the map frame.

    A lidar sees nothing nearer than its range_min (0.12 m on a TurtleBot3, whose body reaches
    0.105 m): an obstacle the robot creeps towards leaves the scan just before contact (its
    beams there all ``-inf``). A point stays while the robot is within ``MEMORY_RADIUS`` of it
    and no later beam in its direction measures anything: a measured direction is the newest
    scan's alone, so what moved away (a neighbour) is forgotten, and the range noise of a wall
    seen again and again does not pile up into a wall nearer than the real one (a robot beside
    a pillar it has room to pass would be blocked by the nearest of its many noisy returns)."""

    def __init__(self) -> None:
        self.points = np.zeros((0, 2))

    def update(self, scan: Scan, pose: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Take a scan taken at ``pose`` and its hit ``points (M, 2)`` (map frame); the points
        kept near the robot (the new ones among them)."""
        p = np.asarray(pose[:2], dtype=np.float64)
        old = self.points[np.hypot(*(self.points - p).T) <= MEMORY_RADIUS]
        if len(old):
            old = old[~scan.measures(old, pose)]
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        kept = np.concatenate([pts[np.hypot(*(pts - p).T) <= MEMORY_RADIUS], old])
        # One point per MEMORY_CELL (the first), by a 1-D key: np.unique over rows is slow.
        cell = np.floor(kept / MEMORY_CELL).astype(np.int64)
        _, first = np.unique(cell[:, 0] * _KEY_STRIDE + cell[:, 1], return_index=True)
        self.points = kept[np.sort(first)]
        return self.points


class SafetyFilter:
    """Cuts v until the predicted arc is clear (see module docstring)."""

    def __init__(self, domain: CoverageDomain, config: SafetyConfig) -> None:
        self.config = config
        self.set_domain(domain)

    def set_domain(self, domain: CoverageDomain) -> None:
        """Check against another map from now on (an exploring robot's map grows)."""
        self.domain = domain
        # [m] distance of every cell centre to the nearest obstacle cell, and the clearance a
        # robot centre needs (what the configuration space is inflated by).
        self.clearance = domain.clearance
        self.needed = self.config.radius + 0.5 * domain.resolution

    def filter(self, pose: np.ndarray, v: float, w: float,
               neighbours: np.ndarray | None = None, neighbour_radii: np.ndarray | None = None,
               scan_points: np.ndarray | None = None,
               neighbour_velocities: np.ndarray | None = None) -> tuple[float, float, str]:
        """``(v, w, reason)``; reason is "" when the command passed unchanged.
        ``neighbour_velocities``: ``(N, 2)`` [m/s] map frame, NaN rows where unknown."""
        why = ""
        for scale in SAFE_SCALES:
            vs = v * scale
            blocked = self._blocked(pose, vs, w, neighbours, neighbour_radii, scan_points,
                                    neighbour_velocities)
            if not blocked:
                return vs, w, "" if scale == 1.0 else f"slowed: {why}"
            why = blocked
        return 0.0, w, f"stopped: {why}"

    def _arc(self, pose: np.ndarray, v: float, w: float) -> tuple[np.ndarray, np.ndarray]:
        """The arc's points ``(n, 2)`` and their times ``(n,)`` [s]."""
        c = self.config
        T = c.horizon + abs(v) / c.a_max
        length = abs(v) * T
        n = max(2, int(math.ceil(length / (CHECK_STEP_CELLS * self.domain.resolution))) + 1)
        t = np.linspace(0.0, T, n)
        return unicycle(pose, v, w, t)[:, :2], t

    def obstacles_near(self, position: np.ndarray, reach: float,
                       scan_points: np.ndarray | None = None) -> np.ndarray:
        """``(N, 2)`` map-frame obstacles within ``reach`` [m] of ``position``: the centres of
        the map's obstacle cells and the given lidar points."""
        geo = self.domain.geometry
        cells = geo.world_to_cell(np.asarray(position[:2], dtype=np.float64)[None, :])[0]
        k = int(math.ceil(reach / self.domain.resolution))
        r0, c0 = max(cells[0] - k, 0), max(cells[1] - k, 0)
        window = self.clearance[r0:cells[0] + k + 1, c0:cells[1] + k + 1]
        rows, cols = np.nonzero(window <= 0.0)
        pts = geo.cell_centers(np.stack([rows + r0, cols + c0], axis=-1)).reshape(-1, 2)
        if scan_points is not None and len(scan_points):
            pts = np.vstack([pts, np.asarray(scan_points, dtype=np.float64).reshape(-1, 2)])
        near: np.ndarray = pts[np.hypot(*(pts - position[:2]).T) <= reach]
        return near

    def _clearance_at(self, pts: np.ndarray) -> np.ndarray:
        cells = self.domain.geometry.world_to_cell(pts)
        inside = self.domain.geometry.contains_cell(cells)
        out = np.zeros(len(pts))
        out[inside] = self.clearance[cells[inside, 0], cells[inside, 1]]
        return out

    def _blocked(self, pose: np.ndarray, v: float, w: float, neighbours: np.ndarray | None,
                 radii: np.ndarray | None, scan_points: np.ndarray | None,
                 velocities: np.ndarray | None = None) -> str:
        if abs(v) < 1e-9:
            return ""
        c = self.config
        arc, times = self._arc(np.asarray(pose, dtype=np.float64), v, w)
        clear = self._clearance_at(arc)
        # Into the inflated zone, and closer to the obstacle than now: a robot already too
        # close (pushed, or started there) may still move away.
        if np.any((clear[1:] < self.needed) & (clear[1:] < clear[0] - 1e-9)):
            return "wall ahead"
        p0 = arc[0]
        if neighbours is not None and len(neighbours):
            nb = np.asarray(neighbours, dtype=np.float64).reshape(-1, 2)
            r = np.broadcast_to(np.asarray(radii if radii is not None else c.radius,
                                           dtype=np.float64), (len(nb),))
            need = c.clearance_to(r)
            d_now = np.hypot(*(nb - p0).T)
            d_arc = np.hypot(arc[1:, None, 0] - nb[None, :, 0],
                             arc[1:, None, 1] - nb[None, :, 1]).min(axis=0)
            if np.any((d_arc < need) & (d_arc < d_now - 1e-6)):
                return "robot ahead"
            if velocities is not None:
                vel = np.asarray(velocities, dtype=np.float64).reshape(-1, 2)
                known = np.isfinite(vel).all(axis=1)
                if known.any():  # where the moving ones will be at the arc's times
                    ahead = nb[known][None] + times[1:, None, None] * vel[known][None]
                    d_then = np.hypot(arc[1:, None, 0] - ahead[..., 0],
                                      arc[1:, None, 1] - ahead[..., 1])
                    # (closer than standing still would leave it: a neighbour that drives at
                    # this robot is its own filter's business, and stopping would not help)
                    d_stand = np.hypot(p0[0] - ahead[..., 0], p0[1] - ahead[..., 1])
                    if np.any((d_then < need[known]) & (d_then < d_now[known] - 1e-6)
                              & (d_then < d_stand - 1e-6)):
                        return "robot ahead, closing in"
        if scan_points is not None and len(scan_points):
            sp = np.asarray(scan_points, dtype=np.float64).reshape(-1, 2)
            reach = float(np.hypot(*(arc[-1] - p0))) + c.radius + 0.2
            near = sp[np.hypot(*(sp - p0).T) < reach]
            if len(near):
                d_arc = np.hypot(arc[1:, None, 0] - near[None, :, 0],
                                 arc[1:, None, 1] - near[None, :, 1]).min(axis=0)
                d_now = np.hypot(*(near - p0).T)
                if np.any((d_arc < c.radius + c.obstacle_margin) & (d_arc < d_now - 1e-6)):
                    return "obstacle in scan"
        return ""
