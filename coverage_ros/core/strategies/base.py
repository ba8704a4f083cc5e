"""The strategy interface shared by the robot node and the offline planner.

A strategy is one robot's coverage brain. It is built once from a :class:`StrategyContext`
(the domain, the robot's :class:`RobotSpec`) and its own settings - a frozen dataclass, the
strategy's :attr:`Strategy.Params`, validated once where the user gave them (node parameters,
CLI, YAML; see :func:`coverage_ros.core.strategies.strategy_choice`). It is then called every
control period with what a real robot has: its own :class:`Observation` (pose, time,
optionally a lidar scan) and the :class:`Neighbour` states its neighbours published. It returns
a :class:`Decision`: where to go (a goal for the robot's navigation) or, for strategies that
steer themselves (TangentBug), a velocity command; the point it is heading for; its own cell
and cost; what it is doing (``mode``); the :class:`SharedState` to publish for the others; and
its own typed :class:`StrategyDetails`.

Strategies keep their own state between calls (caches, virtual generators, modes) but never
touch ROS, the simulator or the viewer.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from coverage_ros.core.exploration.belief import BeliefSnapshot
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.errors import ConfigError


@dataclass(frozen=True)
class Scan:
    """A planar range scan in the robot frame (REP 117: inf = no return)."""

    ranges: np.ndarray  # (B,) [m]
    angle_min: float  # [rad]
    angle_increment: float  # [rad]
    range_min: float  # [m]
    range_max: float  # [m]

    def angles(self) -> np.ndarray:
        return self.angle_min + self.angle_increment * np.arange(len(self.ranges))

    def points(self, pose: np.ndarray | None = None) -> np.ndarray:
        """``(M, 2)`` hit points (finite returns within limits), robot frame or, given a pose
        ``(x, y, yaw)``, map frame."""
        r = np.asarray(self.ranges, dtype=np.float64)
        ok = np.isfinite(r) & (r >= self.range_min) & (r <= self.range_max)
        a = self.angles()[ok]
        if pose is not None:
            a = a + pose[2]
        pts = np.stack([r[ok] * np.cos(a), r[ok] * np.sin(a)], axis=-1)
        if pose is not None:
            pts = pts + np.asarray(pose[:2])
        return pts

    def _beams(self, points: np.ndarray, pose: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each map-frame point's distance from the sensor, its nearest beam's index and
        whether that beam exists (a scan narrower than a full circle misses some directions)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        rel = pts - np.asarray(pose[:2], dtype=np.float64)
        dist = np.hypot(rel[:, 0], rel[:, 1])
        beams = len(self.ranges)
        k = np.rint((np.arctan2(rel[:, 1], rel[:, 0]) - pose[2] - self.angle_min)
                    / self.angle_increment).astype(np.int64)
        if self.full_circle:
            k %= beams  # a full circle wraps
        inside = (k >= 0) & (k < beams)
        return dist, np.where(inside, k, 0), inside

    @property
    def full_circle(self) -> bool:
        """Whether the beams go all the way round (the last beam's neighbour is the first)."""
        return abs(len(self.ranges) * self.angle_increment - 2.0 * np.pi) < 1e-6

    def depths(self) -> np.ndarray:
        """``(B,)`` [m] how far each beam saw free space: its return, ``range_max`` for no
        return within it (REP 117 ``+inf``), 0 for an invalid return (NaN, closer than
        ``range_min``)."""
        r = np.asarray(self.ranges, dtype=np.float64)
        return np.where(np.isnan(r) | (r < self.range_min), 0.0,
                        np.where(np.isinf(r) & (r > 0), self.range_max,
                                 np.minimum(r, self.range_max)))

    def sees(self, points: np.ndarray, pose: np.ndarray,
             depths: np.ndarray | None = None) -> np.ndarray:
        """``(N,) bool``: which map-frame ``points (N, 2)`` the scan taken at ``pose`` saw as
        free - no nearer than its nearest beam's return (no return: free up to
        ``range_max``, REP 117; an invalid return shows nothing). ``depths`` replaces
        :meth:`depths` (e.g. with shadows bridged)."""
        dist, k, inside = self._beams(points, pose)
        depth = self.depths() if depths is None else np.asarray(depths, dtype=np.float64)
        seen: np.ndarray = inside & (dist <= depth[k])
        return seen

    def measures(self, points: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """``(N,) bool``: which map-frame ``points (N, 2)`` lie in the direction of a beam of
        the scan taken at ``pose`` that returned a measurement (a range, or ``+inf``: nothing
        within range_max); not those behind a beam too close to measure (``-inf``), a NaN, or
        outside the scan's field of view."""
        _, k, inside = self._beams(points, pose)
        r = np.asarray(self.ranges, dtype=np.float64)
        valid = ~np.isnan(r) & (r >= self.range_min)
        measured: np.ndarray = inside & valid[k]
        return measured


@dataclass(frozen=True)
class Observation:
    robot_id: int
    pose: np.ndarray  # (3,) x [m], y [m], yaw [rad] in the map frame
    time: float  # [s]
    scan: Scan | None = None
    #: What the robot believes of the map, when it explores an unknown one (else None).
    belief: BeliefSnapshot | None = None
    #: (3,) where the robot stood when it took ``scan`` (None: at ``pose``). A scan is older
    #: than the pose (a lidar turns at 5 Hz, odometry comes at 10 Hz or more); placed from the
    #: newer pose, a scan taken while turning lands rotated by as much as the robot turned since.
    scan_pose: np.ndarray | None = None

    @property
    def position(self) -> np.ndarray:
        return np.asarray(self.pose[:2], dtype=np.float64)

    @property
    def scan_origin(self) -> np.ndarray:
        """(3,) the pose the scan is placed from: :attr:`scan_pose`, else :attr:`pose`."""
        return np.asarray(self.pose if self.scan_pose is None else self.scan_pose,
                          dtype=np.float64)


@dataclass(frozen=True)
class SharedState:
    """What a robot publishes for its neighbours."""

    position: np.ndarray  # (2,) [m] generator position
    weight: float = 0.0  # power weight R [m]
    mass: float | None = None  # own cell mass
    virtual: np.ndarray | None = None  # (2,) virtual generator (Breitenmoser et al.), if any
    #: Further named values of the strategy's protocol, published as they are (e.g. ``reach``);
    #: read-only.
    extra: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "extra", MappingProxyType(dict(self.extra)))


@dataclass(frozen=True)
class Neighbour:
    """A neighbour as known from what it published."""

    robot_id: int
    state: SharedState
    stamp: float = 0.0  # [s] when it was received

    @property
    def position(self) -> np.ndarray:
        return self.state.position


@dataclass(frozen=True)
class StrategyDetails:
    """Base of each strategy's own typed account of an update (subclassed per strategy)."""


#: Every ``Decision.mode`` of the shipped strategies; ``coverage_state`` carries a mode as its
#: index here (``mode``; -1 for one not listed), as the coverage state's ``mode`` constant.
MODES = ("lloyd", "greedy", "frontier", "done", "stay", "cvt", "dropout", "plain", "guided",
         "escape", "motion_to_goal", "boundary_following", "projecting", "reached",
         "projected", "blocked", "seek", "relocate", "make_way")


def mode_code(mode: str) -> int:
    return MODES.index(mode) if mode in MODES else -1


def mode_name(code: float) -> str:
    """The mode of a ``coverage_state`` code ('' when unknown)."""
    k = int(code) if code == code else -1
    return MODES[k] if 0 <= k < len(MODES) else ""


@dataclass(frozen=True)
class Decision:
    """What a strategy decided in one update."""

    goal: np.ndarray | None  # (2,) [m] map frame, for the robot's navigation; None: stay
    velocity: tuple[float, float] | None  # (v [m/s], w [rad/s]) for self-steering strategies
    cell: np.ndarray  # (n,) node ids of the own cell (may be empty)
    shared: SharedState
    converged: bool
    cost: float  # own cell's coverage cost
    mass: float  # own cell's mass
    #: (2,) [m] the point the robot is heading for: the goal, or a self-steering strategy's
    #: own target (None: the goal).
    target: np.ndarray | None = None
    mode: str = ""  # what the strategy is doing, in a word (e.g. "lloyd", "guided", "greedy")
    cell_polygon: np.ndarray | None = None  # (M, 2) [m] for polygonal cells (BVC)
    details: StrategyDetails = field(default_factory=StrategyDetails)
    #: A phase of the strategy is under way that may move the robot later although it stands
    #: at its goal now (alpha-CVT's dropout): a runner does not take "nobody moves" for done.
    settling: bool = False
    #: [rad] map frame: the heading a self-steering strategy's ``velocity`` steers for, so that
    #: a robot's tracking loop (faster than the strategy's updates) turns towards it between
    #: updates instead of holding a turn rate (None: hold ``velocity`` as it is).
    heading: float | None = None

    def __post_init__(self) -> None:
        if self.target is None and self.goal is not None:
            object.__setattr__(self, "target", self.goal)


@dataclass(frozen=True)
class StrategyContext:
    """What a strategy is built from (fixed for the robot's lifetime)."""

    domain: CoverageDomain
    robot: RobotSpec = field(default_factory=RobotSpec)  # body, limits, sensing, power weight
    robot_id: int = 0
    convergence_tolerance: float = 0.05  # [m] goal closer than this = converged
    seed: int = 0
    #: [m] a robot may take its cell from a whole-map search that another robot on the same
    #: domain made since its last update, when every robot is within this distance of where
    #: that search had it (geodesic; :func:`coverage_ros.core.geodesic.cell.geodesic_cell`)
    search_reuse: float = 0.0

    def __post_init__(self) -> None:
        v = self.convergence_tolerance
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise ConfigError.at("convergence_tolerance", "must be a finite number > 0", v)
        v = self.search_reuse
        if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
            raise ConfigError.at("search_reuse", "must be a finite number >= 0 [m]", v)

    @property
    def weight(self) -> float:
        """[m] this robot's power weight R."""
        return self.robot.power_weight


@dataclass(frozen=True)
class NoParams:
    """Settings of a strategy that has none."""


class Strategy(ABC):
    """Base class; subclasses set :attr:`name` and :attr:`Params` and implement
    :meth:`update`."""

    name: ClassVar[str]
    #: The strategy's settings: a frozen dataclass validated in its ``__post_init__``.
    Params: ClassVar[type] = NoParams
    #: Whether the strategy needs lidar scans in its observations.
    needs_scan: ClassVar[bool] = False
    #: Whether the strategy explores an unknown map (it then needs ``Observation.belief``).
    explores: ClassVar[bool] = False
    #: Whether the strategy needs the map of the area; one that does not works from its
    #: lidar alone on a domain where every cell is free (robot_node ``map_free``).
    needs_map: ClassVar[bool] = True

    def __init__(self, context: StrategyContext, params: Any = None) -> None:
        if params is None:
            params = self.Params()
        if not isinstance(params, self.Params):
            raise ConfigError.at(f"strategy {self.name}", "settings of the wrong kind",
                                 type(params).__name__, self.Params.__name__)
        self.context = context
        self.params = params

    @abstractmethod
    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        """One control period: compute the own cell and decide where to go."""

    def shared_state(self, obs: Observation) -> SharedState:
        """What to publish before the first update (default: the own position)."""
        return SharedState(position=obs.position.copy(), weight=self.context.weight)

    def describe(self) -> list[str]:
        """Lines for the robot's log at the end of a run (default: none)."""
        return []

    def cost_about(self, decision: Decision, point: np.ndarray) -> float | None:
        """Coverage cost of ``decision``'s own cell about another position ``point`` (2,) [m],
        or None when the strategy has no such cost. The offline runner's monotone step rule
        uses it: a step that raises it is shortened."""
        return None
