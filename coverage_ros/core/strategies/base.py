"""The strategy interface shared by the robot node and the offline planner.

A strategy is one robot's coverage brain. It is built once from a :class:`StrategyContext`
(the domain, the robot's body and sensing, its parameters) and then called every control
period with what a real robot has: its own :class:`Observation` (pose, time, optionally a lidar
scan) and the :class:`Neighbour` states its neighbours published. It returns a
:class:`Decision`: where to go (a goal for the robot's navigation) or, for strategies that steer
themselves (TangentBug), a velocity command; its own cell; and the :class:`SharedState` to
publish for the others.

Strategies keep their own state between calls (caches, virtual generators, modes) but never
touch ROS, the simulator or the viewer.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from coverage_ros.core.domain import CoverageDomain
from coverage_ros.core.world import RobotSpec
from coverage_ros.errors import ConfigError

#: [m] default sensing radius for coverage metrics: the LDS-01 lidar's range.
DEFAULT_SENSOR_RADIUS = 3.5


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


@dataclass(frozen=True)
class Observation:
    robot_id: int
    pose: np.ndarray  # (3,) x [m], y [m], yaw [rad] in the map frame
    time: float  # [s]
    scan: Scan | None = None

    @property
    def position(self) -> np.ndarray:
        return np.asarray(self.pose[:2], dtype=np.float64)


@dataclass(frozen=True)
class SharedState:
    """What a robot publishes for its neighbours."""

    position: np.ndarray  # (2,) [m] generator position
    weight: float = 0.0  # power weight R [m]
    mass: float | None = None  # own cell mass
    virtual: np.ndarray | None = None  # (2,) virtual generator (seed 001), if any
    extra: Mapping[str, float] = field(default_factory=dict)


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
class Decision:
    goal: np.ndarray | None  # (2,) [m] map frame, or None to stay
    velocity: tuple[float, float] | None  # (v [m/s], w [rad/s]) for self-steering strategies
    cell: np.ndarray  # (n,) node ids of the own cell (may be empty)
    shared: SharedState
    converged: bool
    cost: float  # own cell's coverage cost
    mass: float  # own cell's mass
    cell_polygon: np.ndarray | None = None  # (M, 2) [m] for polygonal cells (BVC)
    info: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class StrategyContext:
    """What a strategy is built from (fixed for the robot's lifetime)."""

    domain: CoverageDomain
    robot: RobotSpec = field(default_factory=RobotSpec)
    robot_id: int = 0
    sensor_radius: float = DEFAULT_SENSOR_RADIUS  # [m]
    weight: float = 0.0  # power weight R [m]
    convergence_tolerance: float = 0.05  # [m] goal closer than this = converged
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("sensor_radius", "convergence_tolerance"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ConfigError.at(name, "must be a finite number > 0", v)
        if not (math.isfinite(self.weight) and self.weight >= 0):
            raise ConfigError.at("power_weight", "must be a finite number >= 0", self.weight)


class Strategy(ABC):
    """Base class; subclasses set :attr:`name` and implement :meth:`update`."""

    name: ClassVar[str]
    #: Whether the strategy needs lidar scans in its observations.
    needs_scan: ClassVar[bool] = False

    def __init__(self, context: StrategyContext, **params: Any) -> None:
        self.context = context
        if params:
            raise ConfigError.at(f"strategy {self.name}", "unknown parameters",
                                 sorted(params), "none")

    @abstractmethod
    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        """One control period: compute the own cell and decide where to go."""

    def shared_state(self, obs: Observation) -> SharedState:
        """What to publish before the first update (default: the own position)."""
        return SharedState(position=obs.position.copy(), weight=self.context.weight)
