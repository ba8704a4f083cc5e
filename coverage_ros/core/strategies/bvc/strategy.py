"""Sensor-based coverage in buffered Voronoi cells with a deadlock-aware guided map (Wang et al.
2024, "Sensor-based multi-agent coverage control with spatial separation in unstructured
environments").

Every control period the robot

1. builds its buffered Voronoi cell (Eq. 4-7, :mod:`.cells`) from the current lidar points
   within its sensing radius and its neighbours' positions - a convex polygon that keeps its
   body at least its radius away from every sensed point and from every neighbour's cell;
2. in guided mode (default) remembers the lidar hits, picks the highest-density point it can
   reach within sensing range and inside its own Voronoi region as goal, and replaces the
   density by ``phi = exp(-gamma M_go)`` with ``M_go`` the cost-to-go to that goal over what it
   has seen (Eq. 8, :mod:`.guide` on :mod:`.guided_map`); with ``seek_peaks`` a robot whose
   neighbour keeps the peak heads for a peak nobody attends, or covers round the others if
   none is left (:mod:`.peaks`); in plain mode it keeps the importance density (the classic
   move-to-centroid policy, which stalls behind non-convex obstacles);
3. moves towards the centroid ``C`` of its cell under that density (Eq. 3). The decision's
   goal is ``C`` itself: it lies in the convex cell, so the straight move there is
   collision-free (Theorem 1), and the robot's navigation drives there at no more than its
   speed limit - the saturation of Eq. 3. ``BvcDetails.u`` is Eq. 3's velocity,
   ``(C - p) / dt`` capped at ``u_max`` (``dt`` from the observation times), for runners that
   integrate single integrators (:func:`coverage_ros.bench.peak_trials.run_trial`). The robot
   has converged when ``|u|`` drops below ``converged_speed`` (0.01 m/s in the paper).

A centroid can stall short of the goal where two equally short paths pull it in opposite
directions (a saddle of the smoothed field, likelier with a small ``gamma``); if its cell still
holds a point clearly closer to the goal, the robot then heads for the cell's point of least
cost-to-go (``Decision.mode == "escape"``), the ``gamma -> inf`` limit of Eq. 8.

The importance density is the domain's raster (the "GIS prior"; it is zero on the map's blocked
cells, so a goal is never picked inside a known obstacle). Obstacles are otherwise known only
from the scans: the robot's safety never depends on the map.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from coverage_ros.core.control.period import ControlPeriod
from coverage_ros.core.geometry import points_in_polygon
from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    SharedState,
    Strategy,
    StrategyContext,
    StrategyDetails,
)
from coverage_ros.core.strategies.bvc.cells import (
    BufferedCell,
    buffered_cell,
    convex_polygon_cells,
)
from coverage_ros.core.strategies.bvc.guide import Guide
from coverage_ros.core.strategies.bvc.memory import ObstacleMemory
from coverage_ros.errors import ConfigError

#: [m] lidar points this close to a neighbour's body are the neighbour, not a wall: they are
#: kept out of the obstacle memory (the bisector already separates the robots). Covers pose
#: latency (0.22 m/s for ~0.3 s) and range noise.
NEIGHBOUR_POINT_MARGIN = 0.1
#: A centroid closer than the arrival tolerance that keeps moving ahead is sent to the
#: navigation this many tolerances along (see BvcStrategy._navigation_goal).
EXTEND_FACTOR = 1.5
#: [grid cells] a cell point must be this much closer to the goal (in cost-to-go) than the robot
#: for a stalled centroid to count as a deadlock rather than arrival (grid distances are exact
#: only to about a cell).
ESCAPE_DESCENT_CELLS = 2.0


@dataclass(frozen=True)
class BvcParams:
    """Parameters of the ``bvc`` strategy (see README "Strategy bvc")."""

    guided: bool = True  # deadlock-aware guided map (False: plain move-to-centroid)
    gamma: float = 10.0  # [1/m] gain of Eq. 8, phi = exp(-gamma * M_go)
    u_max: float | None = None  # [m/s] speed cap of Eq. 3 (None: the robot's v_max)
    period: float = 0.2  # [s] nominal control period (used until obs.time gives one)
    converged_speed: float = 0.01  # [m/s] converged when |u| falls below this
    grid_resolution: float = 0.1  # [m] cells of the obstacle memory and navigation function
    nf_radius: float | None = None  # [m] half-width of the navigation window (None: 2 R_sensor)
    #: [m] uniform density: the shadows of obstacles narrower than this (pillars, teammates)
    #: count as seen free (0: only what the beams reached); see memory.bridge_shadows
    bridge_width: float = 0.5
    #: a robot with no peak of its own in range heads for one no robot attends, or covers
    #: round the owners (Lloyd) if none is left (.peaks)
    seek_peaks: bool = True

    def __post_init__(self) -> None:
        for flag in ("guided", "seek_peaks"):
            if not isinstance(getattr(self, flag), bool):
                raise ConfigError.at(f"bvc.{flag}", "must be true or false", getattr(self, flag))
        for name in ("gamma", "period", "converged_speed", "grid_resolution", "u_max",
                     "nf_radius", "bridge_width"):
            value = getattr(self, name)
            if value is None and name in ("u_max", "nf_radius"):
                continue
            zero_ok = name in ("gamma", "bridge_width")
            ok = isinstance(value, int | float) and not isinstance(value, bool) \
                and math.isfinite(value) and (value >= 0 if zero_ok else value > 0)
            if not ok:
                expected = "a finite number >= 0" if zero_ok else "a finite number > 0"
                raise ConfigError.at(f"bvc.{name}", "invalid value", value, expected)


@dataclass(frozen=True)
class BvcDetails(StrategyDetails):
    u: np.ndarray  # (2,) [m/s] Eq. 3's velocity toward the centroid, capped at u_max
    speed: float  # [m/s] |u|
    guide_goal: np.ndarray | None  # (2,) [m] p_g of the guided map, if any
    buffer: float  # [m] the cell's buffer (the robot radius)
    obstacle_planes: int  # robot-obstacle hyperplanes bounding the cell
    reason: str = ""  # why the robot stays, when it does


class BvcStrategy(Strategy):
    """Buffered Voronoi cells from lidar points, guided by a navigation function."""

    name: ClassVar[str] = "bvc"
    Params: ClassVar[type] = BvcParams
    params: BvcParams
    needs_scan: ClassVar[bool] = True
    needs_map: ClassVar[bool] = False  # cells, goals and safety from the lidar (Wang et al.)

    def __init__(self, context: StrategyContext, params: BvcParams | None = None) -> None:
        super().__init__(context, params)
        self.radius = float(context.robot.radius)
        # R_sensor: the sensing radius, but never beyond what the lidar can see.
        self.sensor_radius = min(float(context.robot.sensor_radius),
                                 float(context.robot.lidar.range_max))
        if self.sensor_radius <= self.radius:
            raise ConfigError.at("sensor_radius", "must exceed the robot radius",
                                 self.sensor_radius, f"> {self.radius}")
        self.u_max = float(self.params.u_max if self.params.u_max is not None
                           else context.robot.v_max)
        self.nf_radius = float(self.params.nf_radius if self.params.nf_radius is not None
                               else 2.0 * self.sensor_radius)
        if self.nf_radius < self.sensor_radius:
            raise ConfigError.at("bvc.nf_radius", "must be at least the sensing radius",
                                 self.nf_radius, f">= {self.sensor_radius}")
        domain = context.domain
        self.bounds = domain.geometry.extent()
        self.memory = ObstacleMemory.covering(self.bounds, self.params.grid_resolution)
        self.guide = Guide(domain, self.memory, self.radius, self.sensor_radius, self.nf_radius,
                           self.params.gamma, self.params.bridge_width, self.params.seek_peaks)
        self.clock = ControlPeriod(self.params.period)
        self._last_step: np.ndarray | None = None  # centroid - position at the last update
        self._extended = False  # the last navigation goal lay beyond the centroid
        self._overshot = False  # ... and the centroid then turned back: no more until moving

    # ------------------------------------------------------------------ interface
    def shared_state(self, obs: Observation) -> SharedState:
        return SharedState(position=obs.position.copy(), weight=self.context.weight,
                           extra={"radius": self.radius})

    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        p = obs.position
        dt = self.clock.elapsed(obs.time)
        if obs.scan is None:
            return self._stay(p, "no scan yet")
        points = obs.scan.points(obs.scan_origin)  # placed from where the scan was taken
        nb = np.array([n.position for n in neighbours], dtype=np.float64).reshape(-1, 2)
        nb_r = np.array([float(n.state.extra.get("radius", self.radius)) for n in neighbours])
        self.memory.add(_away_from(points, nb, nb_r + NEIGHBOUR_POINT_MARGIN))
        cell = buffered_cell(p, points, nb, self.radius, self.sensor_radius, self.bounds)
        if len(cell.polygon) < 3:
            return self._stay(p, "empty cell", cell)
        nodes, xy, wdA = self._samples(cell)
        phi, mode, field = wdA, "plain", None
        if self.params.guided:
            field = self.guide.field(p, xy, cell, obs, (nb, nb_r))
            if field is not None:
                phi, mode = field.phi, "guided"
        total = float(phi.sum())
        target = (xy * phi[:, None]).sum(axis=0) / total if total > 0 else p.copy()
        speed = self._speed(target - p, dt)
        if field is not None and speed < self.params.converged_speed:
            # A stalled centroid short of the goal (see module docstring): head for the cell's
            # point of least cost-to-go, the gamma -> inf limit of Eq. 8 (ties: first sample).
            k = int(np.argmin(field.cost))
            if field.cost[k] < field.cost_here - ESCAPE_DESCENT_CELLS * self.memory.resolution:
                target, mode = xy[k].copy(), "escape"
                speed = self._speed(target - p, dt)
        step = target - p
        dist = float(np.hypot(*step))
        u = step * (speed / dist) if dist > 0 else np.zeros(2)
        goal = self._navigation_goal(p, target, step, dist, cell)
        d2 = ((xy - p) ** 2).sum(axis=1)
        mass = float(wdA.sum())
        free = self.context.domain.free.ravel()[nodes]
        return Decision(
            goal=goal, target=target, velocity=None, cell=nodes[free],
            shared=SharedState(position=p.copy(), weight=self.context.weight, mass=mass,
                               extra={"radius": self.radius}),
            converged=speed < self.params.converged_speed, cost=float((d2 * wdA).sum()),
            mass=mass, mode=mode, cell_polygon=cell.polygon,
            details=BvcDetails(u=u, speed=speed,
                               guide_goal=None if field is None else field.goal,
                               buffer=cell.buffer, obstacle_planes=len(cell.obstacle_planes)))

    # ------------------------------------------------------------------ helpers
    def _navigation_goal(self, p: np.ndarray, target: np.ndarray, step: np.ndarray,
                         dist: float, cell: BufferedCell) -> np.ndarray:
        """Where the robot's navigation is sent: the centroid, except when it lies closer than
        the navigation's arrival tolerance while the centroid keeps moving ahead of the robot
        (the same direction as last update - a cell face that recedes as the robot follows
        it): then a point of the cell that far along, so that the robot keeps following Eq.
        3 instead of parking. A centroid that turned back (overshoot) is sent as it is, and
        after an extended goal was overshot there is no other until the centroid lies a
        tolerance away again: near a balance (two robots sharing a peak) extending would make
        the robots hunt around it for ever."""
        tol = self.context.convergence_tolerance
        last, self._last_step = self._last_step, step.copy()
        ahead_again = last is not None and float(step @ last) > 0.0
        self._overshot = dist < tol and (self._overshot or (self._extended and not ahead_again))
        self._extended = False
        if not (1e-3 < dist < tol) or not ahead_again or self._overshot:
            return target
        ahead = p + step * (EXTEND_FACTOR * tol / dist)
        self._extended = bool(points_in_polygon(ahead[None], cell.polygon)[0])
        return ahead if self._extended else target

    def _stay(self, p: np.ndarray, reason: str, cell: BufferedCell | None = None) -> Decision:
        return Decision(goal=p.copy(), velocity=None, cell=np.zeros(0, np.int64),
                        shared=SharedState(position=p.copy(), weight=self.context.weight,
                                           extra={"radius": self.radius}),
                        converged=False, cost=0.0, mass=0.0, mode="stay",
                        cell_polygon=None if cell is None else cell.polygon,
                        details=BvcDetails(u=np.zeros(2), speed=0.0, guide_goal=None,
                                           buffer=self.radius, obstacle_planes=0,
                                           reason=reason))

    def _samples(self, cell: BufferedCell) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Domain nodes whose centre lies in the cell, the centres ``(N, 2)`` and their mass
        elements (density * area)."""
        domain = self.context.domain
        rows, cols = convex_polygon_cells(domain.to_grid(cell.polygon), domain.shape)
        nodes = rows * domain.shape[1] + cols
        xy = domain.to_map(domain.node_centers(nodes))
        return nodes, xy, domain.mass_element.ravel()[nodes]

    def _speed(self, step: np.ndarray, dt: float) -> float:
        """|u| of Eq. 3 towards a target ``step`` away: ``|step| / dt`` capped at ``u_max``."""
        return min(self.u_max, float(np.hypot(*step)) / dt)


def _away_from(points: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """The ``points (N, 2)`` farther than ``radii (J,)`` from every one of ``centres (J, 2)``."""
    if len(centres) == 0 or len(points) == 0:
        return points
    d = np.hypot(points[:, None, 0] - centres[None, :, 0],
                 points[:, None, 1] - centres[None, :, 1])
    return points[np.all(d > radii[None, :], axis=1)]

