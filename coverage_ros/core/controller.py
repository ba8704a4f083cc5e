"""One robot's coverage controller, independent of ROS (the robot node only feeds it).

Two loops, as on the real robot:

* :meth:`RobotController.update` (the coverage period, a few Hz): the strategy computes the own
  cell from the robot's pose, scan and the neighbours it currently trusts, and decides a goal
  (then a path is planned to it) or a velocity; also returns the state to publish.
* :meth:`RobotController.command` (the tracking period, ~10 Hz): the tracker follows the path
  (or the strategy's velocity is used), and the safety filter has the last word.

Neighbours are known only from what they published (:class:`NeighbourTable`): entries with
non-finite values, positions off the map, or older than ``neighbour_timeout`` are ignored.

The two loops may run in different threads (the robot node computes updates off its executor
thread so that tracking never waits for a large cell): :meth:`update` works on a snapshot of
the inputs and commits its result under a lock that :meth:`command` also takes; updates must
not run concurrently with each other.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from coverage_ros.core.domain import CoverageDomain
from coverage_ros.core.navigation import (
    PathTracker,
    SafetyConfig,
    SafetyFilter,
    TrackerConfig,
    plan_path,
)
from coverage_ros.core.strategies import (
    STRATEGIES,
    Decision,
    Neighbour,
    Observation,
    Scan,
    SharedState,
    StrategyContext,
    make_strategy,
)
from coverage_ros.core.world import RobotSpec
from coverage_ros.errors import ConfigError

#: [m] a neighbour may be reported this far outside the map's extent (localisation noise).
MAP_MARGIN = 0.5
#: [s] neighbours' positions are grown by v_max x their age, up to this age (older ones
#: are stale and dropped by the neighbour timeout anyway; the lidar sees them meanwhile).
MAX_NEIGHBOUR_AGE = 0.5
#: [m] goal changes smaller than this keep the current path (no replanning jitter).
REPLAN_DISTANCE = 0.05
STATE_KEYS = ("x", "y", "weight", "mass", "cost", "update_ms")


@dataclass(frozen=True)
class ControllerConfig:
    robot_id: int
    strategy: str = "geodesic"
    strategy_params: dict[str, Any] = field(default_factory=dict)
    robot: RobotSpec = field(default_factory=RobotSpec)
    sensor_radius: float = 3.5  # [m]
    power_weight: float = 0.0  # [m]
    comm_range: float = 0.0  # [m] 0 = unlimited
    neighbour_timeout: float = 2.0  # [s]
    goal_tolerance: float = 0.05  # [m]

    def __post_init__(self) -> None:
        if self.robot_id < 0:
            raise ConfigError.at("robot_id", "must be >= 0", self.robot_id)
        if self.strategy not in STRATEGIES:
            raise ConfigError.at("strategy", "unknown strategy", self.strategy,
                                 f"one of {sorted(STRATEGIES)}")
        for name in ("comm_range", "power_weight"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError.at(name, "must be a finite number >= 0", v)
        for name in ("sensor_radius", "neighbour_timeout", "goal_tolerance"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError.at(name, "must be a finite number > 0", v)


@dataclass
class _Entry:
    state: SharedState
    received: float  # [s] node clock when received


class NeighbourTable:
    """The latest valid state of every other robot, by id."""

    def __init__(self, extent: tuple[float, float, float, float], timeout: float) -> None:
        self.extent = extent
        self.timeout = timeout
        self.entries: dict[int, _Entry] = {}
        self._lock = threading.Lock()

    def receive(self, robot_id: int, values: dict[str, float], now: float) -> str:
        """Store a neighbour's published values; returns "" or why they were rejected."""
        for key, v in values.items():
            if key in STATE_KEYS[:4] and not math.isfinite(v):
                return f"{key} is {v!r}"
        x, y = values["x"], values["y"]
        xmin, ymin, xmax, ymax = self.extent
        if not (xmin - MAP_MARGIN <= x <= xmax + MAP_MARGIN
                and ymin - MAP_MARGIN <= y <= ymax + MAP_MARGIN):
            return f"position ({x:.2f}, {y:.2f}) is outside the map"
        weight = values.get("weight", 0.0)
        if weight < 0:
            return f"weight {weight!r} < 0"
        virtual = None
        if "virtual_x" in values and "virtual_y" in values:
            virtual = np.array([values["virtual_x"], values["virtual_y"]])
            if not np.all(np.isfinite(virtual)):
                virtual = None
        extra = {k: v for k, v in values.items()
                 if k not in STATE_KEYS and k not in ("virtual_x", "virtual_y")}
        mass = values.get("mass")
        entry = _Entry(SharedState(
            position=np.array([x, y]), weight=weight,
            mass=mass if mass is not None and math.isfinite(mass) else None,
            virtual=virtual, extra=extra), now)
        with self._lock:
            self.entries[robot_id] = entry
        return ""

    def current(self, now: float, own: np.ndarray | None = None, comm_range: float = 0.0,
                ) -> list[Neighbour]:
        """Fresh neighbours (within ``comm_range`` of ``own`` if that is > 0), by id."""
        with self._lock:
            entries = sorted(self.entries.items())
        out = []
        for rid, e in entries:
            if now - e.received > self.timeout:
                continue
            if comm_range > 0 and own is not None and \
                    float(np.hypot(*(e.state.position - own))) > comm_range:
                continue
            out.append(Neighbour(rid, e.state, e.received))
        return out

    def forget(self, robot_id: int) -> None:
        with self._lock:
            self.entries.pop(robot_id, None)


@dataclass
class UpdateResult:
    decision: Decision
    path: np.ndarray | None
    state: dict[str, float]  # the values to publish as coverage_state
    neighbours: list[int]
    pose: np.ndarray  # (x, y, yaw) the update started from


class RobotController:
    """See module docstring."""

    def __init__(self, domain: CoverageDomain, config: ControllerConfig) -> None:
        self.domain = domain
        self.config = config
        ctx = StrategyContext(domain=domain, robot=config.robot, robot_id=config.robot_id,
                              sensor_radius=config.sensor_radius, weight=config.power_weight,
                              convergence_tolerance=config.goal_tolerance,
                              seed=config.robot_id)
        self.strategy = make_strategy(config.strategy, ctx, **config.strategy_params)
        self.neighbours = NeighbourTable(domain.geometry.extent(), config.neighbour_timeout)
        self.tracker = PathTracker(TrackerConfig.for_robot(config.robot,
                                                           goal_tolerance=config.goal_tolerance))
        self.safety = SafetyFilter(domain, SafetyConfig(radius=config.robot.radius,
                                                        a_max=config.robot.a_max))
        self.pose: np.ndarray | None = None
        self.scan: Scan | None = None
        self.scan_points: np.ndarray | None = None
        self.goal: np.ndarray | None = None
        self.path: np.ndarray | None = None
        self.velocity: tuple[float, float] | None = None
        self.last: UpdateResult | None = None
        self.safety_note = ""
        self._lock = threading.Lock()

    @property
    def needs_scan(self) -> bool:
        return self.strategy.needs_scan

    def set_pose(self, pose: tuple[float, float, float]) -> None:
        self.pose = np.asarray(pose, dtype=np.float64)

    def set_scan(self, scan: Scan, points_map: np.ndarray) -> None:
        self.scan, self.scan_points = scan, points_map

    def update(self, now: float) -> UpdateResult | None:
        """One coverage period; None until the robot knows its pose."""
        with self._lock:
            if self.pose is None:
                return None
            pose, scan, goal, path = self.pose.copy(), self.scan, self.goal, self.path
        nbrs = self.neighbours.current(now, pose[:2], self.config.comm_range)
        obs = Observation(self.config.robot_id, pose, now, scan)
        t0 = time.perf_counter()
        decision = self.strategy.update(obs, nbrs)
        update_ms = (time.perf_counter() - t0) * 1e3
        if decision.velocity is None and decision.goal is not None:
            new_goal = np.asarray(decision.goal, dtype=np.float64)
            if goal is None or path is None or float(np.hypot(*(new_goal - goal))) > \
                    REPLAN_DISTANCE:
                goal, path = new_goal, plan_path(self.domain, pose[:2], new_goal)
        shared = decision.shared
        state = {"x": float(shared.position[0]), "y": float(shared.position[1]),
                 "weight": float(shared.weight), "mass": float(decision.mass),
                 "cost": float(decision.cost), "update_ms": update_ms,
                 "radius": float(self.config.robot.radius),
                 "v_max": float(self.config.robot.v_max)}
        if shared.virtual is not None:
            state["virtual_x"], state["virtual_y"] = (float(v) for v in shared.virtual)
        state.update({k: float(v) for k, v in shared.extra.items()})
        result = UpdateResult(decision, path, state, [n.robot_id for n in nbrs], pose)
        with self._lock:
            self.velocity, self.goal, self.path = decision.velocity, goal, path
            self.last = result
        return result

    def presence_state(self) -> dict[str, float]:
        """What to publish before the first update: who and where this robot is, without a
        cell (no mass or cost yet)."""
        x, y = (float(v) for v in self.pose[:2])
        return {"x": x, "y": y, "weight": float(self.config.power_weight),
                "radius": float(self.config.robot.radius),
                "v_max": float(self.config.robot.v_max)}

    def hold(self) -> None:
        """Stop following anything (e.g. after a failed update)."""
        with self._lock:
            self.path, self.velocity = None, (0.0, 0.0)

    def command(self, now: float, dt: float) -> tuple[float, float]:
        """One tracking period: the safe (v, w) to send."""
        with self._lock:
            return self._command(now, dt)

    def _command(self, now: float, dt: float) -> tuple[float, float]:
        if self.pose is None:
            return 0.0, 0.0
        if self.velocity is not None:
            v, w = self.velocity
            v = float(np.clip(v, -self.config.robot.v_max, self.config.robot.v_max))
            w = float(np.clip(w, -self.config.robot.w_max, self.config.robot.w_max))
        else:
            v, w, _ = self.tracker.command(self.pose, self.path, dt)
        nbrs = self.neighbours.current(now)
        positions = np.array([n.position for n in nbrs]).reshape(-1, 2)
        # A neighbour may have moved since it published: grow it by how far it can have gone.
        own = self.config.robot
        radii = np.array([n.state.extra.get("radius", own.radius)
                          + n.state.extra.get("v_max", own.v_max)
                          * min(max(now - n.stamp, 0.0), MAX_NEIGHBOUR_AGE)
                          for n in nbrs])
        v, w, self.safety_note = self.safety.filter(self.pose, v, w, positions, radii,
                                                    self.scan_points)
        self.tracker.override(v, w)
        return v, w
