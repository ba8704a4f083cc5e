"""One robot's coverage controller, independent of ROS (the robot node only feeds it).

Two loops, as on the real robot:

* :meth:`RobotController.update` (the coverage period, a few Hz): the strategy computes the own
  cell from the robot's pose, scan and the neighbours it currently trusts, and decides a goal
  (then a path is planned to it) or a velocity; also returns the state to publish.
* :meth:`RobotController.command` (the tracking period, ~10 Hz): the tracker follows the path
  (or the strategy's velocity is used), and the safety filter has the last word. It steers and
  checks from the pose carried forward to ``now`` under the last command when the pose is
  older than that (a busy process reads its poses late; :mod:`.pose_age`).

Neighbours are known only from what they published (:class:`NeighbourTable`): entries with
non-finite values, positions off the map, or older than ``neighbour_timeout`` are ignored.

Exploring an unknown map, the controller also holds the robot's :class:`Belief`: every scan is
added to it (:meth:`RobotController.integrate_scan`), every update plans on the map the belief
gives at that moment (:func:`~coverage_ros.core.exploration.maps.navigation_domain`: unknown
space traversable at a cost, walls seen so far inflated by the radius), and the safety filter
checks commands against that map and the lidar points.

The loops may run in different threads (the robot node computes updates off its executor
thread): :meth:`update` works on a snapshot of the inputs and commits its result under a lock
that :meth:`command` also takes; updates must not run concurrently with each other.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field, replace

import numpy as np

from coverage_ros.core.control import published_state
from coverage_ros.core.control.make_way import Ways, make_way
from coverage_ros.core.control.neighbours import NeighbourTable, safety_discs
from coverage_ros.core.control.planning import MAX_DETOUR, detour, plan_path
from coverage_ros.core.control.pose_age import PoseAges
from coverage_ros.core.control.recovery import ESCAPE_LOOK, ROBOT_AHEAD, StuckRecovery
from coverage_ros.core.control.region_seek import seek_region
from coverage_ros.core.control.safety import SafetyConfig, SafetyFilter, ScanMemory
from coverage_ros.core.control.tracking import PathTracker, TrackerConfig
from coverage_ros.core.exploration.belief import Belief
from coverage_ros.core.exploration.maps import navigation_domain
from coverage_ros.core.exploration.sensor_model import footprint_cells, scan_cells
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geometry import wrap_angle
from coverage_ros.core.strategies import (
    Decision,
    Neighbour,
    Observation,
    Scan,
    StrategyChoice,
    StrategyContext,
    make_strategy,
    strategy_choice,
)
from coverage_ros.core.world.region import Region
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.errors import ConfigError

#: [m] goal changes smaller than this keep the current path (no replanning jitter).
REPLAN_DISTANCE = 0.05
#: Modes whose goal is a destination elsewhere on the map (a claimed cell's point, a region of
#: interest), not a step within the own cell: planned for however far round the way goes.
DESTINATION_MODES = frozenset({"relocate", "seek"})


@dataclass(frozen=True)
class ControllerConfig:
    robot_id: int
    strategy: StrategyChoice = field(default_factory=lambda: strategy_choice("geodesic"))
    robot: RobotSpec = field(default_factory=RobotSpec)  # body, limits, sensing, power weight
    comm_range: float = 0.0  # [m] 0 = unlimited
    neighbour_timeout: float = 2.0  # [s]
    goal_tolerance: float = 0.05  # [m] a goal step shorter than this: converged
    arrival_tolerance: float = 0.05  # [m] the tracker stops this near its goal
    teleop_timeout: float = 0.5  # [s] a manual robot stops when its person sends nothing
    search_reuse: float = 0.0  # [m] see StrategyContext.search_reuse

    def __post_init__(self) -> None:
        if self.robot_id < 0:
            raise ConfigError.at("robot_id", "must be >= 0", self.robot_id)
        if not isinstance(self.strategy, StrategyChoice):
            raise ConfigError.at("strategy", "must be a validated strategy choice",
                                 self.strategy)
        if not (math.isfinite(self.comm_range) and self.comm_range >= 0):
            raise ConfigError.at("comm_range", "must be a finite number >= 0", self.comm_range)
        for name in ("neighbour_timeout", "goal_tolerance", "arrival_tolerance", "teleop_timeout"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError.at(name, "must be a finite number > 0", v)
        if not (math.isfinite(self.search_reuse) and self.search_reuse >= 0):
            raise ConfigError.at("search_reuse", "must be a finite number >= 0 [m]",
                                 self.search_reuse)


@dataclass
class UpdateResult:
    decision: Decision
    path: np.ndarray | None
    state: dict[str, float]  # the values to publish as coverage_state
    neighbours: list[int]
    pose: np.ndarray  # (x, y, yaw) the update started from


class RobotController:
    """See module docstring."""

    def __init__(self, domain: CoverageDomain, config: ControllerConfig,
                 belief: Belief | None = None) -> None:
        if config.strategy.explore != (belief is not None):
            raise ConfigError.at("strategy", "an exploring strategy needs a belief of the map "
                                 "and only an exploring strategy takes one",
                                 config.strategy.name)
        self.domain = domain
        self._base_domain = domain  # the map's own density (a region restricts a copy)
        self.region = Region()  # everywhere
        self.config = config
        #: What the robot believes of an unknown map (exploring), else None.
        self.belief = belief
        self._planned_version = -1  # belief version the current path was planned on
        self._ways = Ways()  # relocating neighbours' paths (make_way)
        ctx = StrategyContext(domain=domain, robot=config.robot, robot_id=config.robot_id,
                              convergence_tolerance=config.goal_tolerance,
                              seed=config.robot_id, search_reuse=config.search_reuse)
        self.strategy = make_strategy(config.strategy, ctx)
        self.neighbours = NeighbourTable(domain.geometry.extent(), config.neighbour_timeout)
        self.tracker = PathTracker(TrackerConfig.for_robot(
            config.robot, goal_tolerance=config.arrival_tolerance))
        self.safety = SafetyFilter(domain, SafetyConfig(radius=config.robot.radius,
                                                        a_max=config.robot.a_max))
        steer = self.tracker.config
        self.recovery = StuckRecovery(config.robot.v_max, steer.heading_gain,
                                      steer.turn_in_place)
        self.pose: np.ndarray | None = None
        self.pose_stamp: float | None = None  # [s] when the pose was true (None: now)
        self.pose_ages = PoseAges()  # how late the poses of the commands were
        self.scan: Scan | None = None
        self.scan_pose: np.ndarray | None = None  # where the robot took self.scan
        self.scan_points: np.ndarray | None = None
        self.scan_memory = ScanMemory()
        self.goal: np.ndarray | None = None
        self.path: np.ndarray | None = None
        self.velocity: tuple[float, float] | None = None
        self.heading: float | None = None  # [rad] a self-steering strategy's, with velocity
        self.last: UpdateResult | None = None
        self.safety_note = ""
        #: Driven by a person: commands come from :meth:`teleop`, not the strategy (which
        #: keeps computing the cell, so the neighbours see this robot's share).
        self.manual = False
        #: Stopped and holding until resumed (cells and states keep being published).
        self.paused = False
        self._teleop = (0.0, 0.0, -math.inf)  # (v, w, receive time [s])
        self._replan = ""  # why an escape ended: the next update plans a new path
        self.sent: tuple[float, float] | None = None  # the last (v, w) returned by command()
        self._lock = threading.Lock()

    @property
    def needs_scan(self) -> bool:
        return self.strategy.needs_scan or self.belief is not None

    def set_pose(self, pose: tuple[float, float, float], stamp: float | None = None) -> None:
        """The robot's pose in the map frame, true at ``stamp`` [s] (None: at every ``now``)."""
        self.pose = np.asarray(pose, dtype=np.float64)
        self.pose_stamp = None if stamp is None else float(stamp)

    def set_scan(self, scan: Scan, points_map: np.ndarray,
                 pose: tuple[float, float, float] | None = None) -> None:
        """The newest scan and its hit points in the map frame, taken at ``pose`` (default:
        the current pose); the safety filter checks the points kept near the robot."""
        self.scan = scan
        at = self.pose if pose is None else np.asarray(pose, dtype=np.float64)
        self.scan_pose = None if at is None else at.copy()
        if at is not None:  # (without a pose the points cannot be kept about the robot)
            self.scan_points = self.scan_memory.update(scan, at, points_map)

    def integrate_scan(self, scan: Scan, pose: np.ndarray, now: float) -> int:
        """Exploring: add what one scan, taken at ``pose``, saw to the belief (returns on the
        neighbours' bodies are robots, not walls), and the robot's own footprint (free
        ground); how many cells changed."""
        if self.belief is None:
            return 0
        own = self.config.robot
        discs = np.array([(*n.position, n.state.extra.get("radius", own.radius))
                          for n in self.neighbours.current(now)]).reshape(-1, 3)
        cells = scan_cells(self.belief.lattice, pose, scan.ranges, scan.angle_min,
                           scan.angle_increment, scan.range_min, scan.range_max,
                           ignore_discs=discs)
        under = footprint_cells(self.belief.lattice, pose[:2], own.radius)
        return self.belief.add_scan(cells) + self.belief.add_footprint(under)

    def update(self, now: float) -> UpdateResult | None:
        """One coverage period; None until the robot knows its pose."""
        with self._lock:
            if self.pose is None:
                return None
            pose, scan, goal, path = self.pose.copy(), self.scan, self.goal, self.path
            scan_pose = self.scan_pose
            replan = self._replan
        nbrs = self.neighbours.current(now, pose[:2], self.config.comm_range)
        t0 = time.perf_counter()
        snapshot, nav = None, self.domain
        if self.belief is not None:
            snapshot = self.belief.snapshot()
            nav = navigation_domain(snapshot, self.config.robot.radius,
                                    len(self.domain.graph.offsets))
            _ = nav.clearance  # computed here, not under the lock (see _commit)
        obs = Observation(self.config.robot_id, pose, now, scan, snapshot, scan_pose)
        decision = seek_region(self.domain, self.region, self.strategy.update(obs, nbrs), pose)
        decision = make_way(nav, decision, pose, nbrs, self._keep_from, self._ways)
        update_ms = (time.perf_counter() - t0) * 1e3
        if decision.velocity is None and decision.goal is not None:
            new_goal = np.asarray(decision.goal, dtype=np.float64)
            # Exploring, the map grows: a path on an older map may cross a wall found since.
            stale = snapshot is not None and snapshot.version != self._planned_version
            # A robot at its goal follows a new goal beyond the arrival tolerance even when it
            # moved less than REPLAN_DISTANCE: else a goal that creeps a few cm per update (a
            # bvc centroid near equilibrium) never moved the robot again.
            tol = self.tracker.config.goal_tolerance
            arrived = goal is not None and float(np.hypot(*(goal - pose[:2]))) < tol
            if goal is None or path is None or stale or replan or \
                    float(np.hypot(*(new_goal - goal))) > REPLAN_DISTANCE or \
                    (arrived and float(np.hypot(*(new_goal - pose[:2]))) >= tol):
                reach = math.inf if decision.mode in DESTINATION_MODES else MAX_DETOUR
                goal, path = new_goal, plan_path(nav, pose[:2], new_goal, reach)
                if replan == ROBOT_AHEAD:  # it gave way: around the robots in its way
                    P, R, _ = safety_discs(nbrs, now, self.config.robot)
                    path = detour(nav, path, P, self.safety.config.clearance_to(R))
                if snapshot is not None:
                    self._planned_version = snapshot.version
        state = published_state.after_update(decision, self.config.robot, update_ms, self.manual,
                                             self.paused)
        result = UpdateResult(decision, path, state, [n.robot_id for n in nbrs], pose)
        with self._lock:
            self.velocity, self.goal, self.path = decision.velocity, goal, path
            self._replan = "" if replan else self._replan
            self.heading = decision.heading if decision.velocity is not None else None
            self.last = result
            if nav is not self.safety.domain:
                self.safety.set_domain(nav)
        return result

    def _keep_from(self, n: Neighbour) -> float:
        """[m] the centre distance the safety filter keeps from neighbour ``n``."""
        radius = n.state.extra.get("radius", self.config.robot.radius)
        return float(self.safety.config.clearance_to(np.array([radius]))[0])

    def presence_state(self) -> dict[str, float]:
        """What to publish before the first update (:func:`.published_state.before_update`)."""
        assert self.pose is not None, "presence_state needs the robot's pose (set_pose)"
        first = self.strategy.shared_state(Observation(self.config.robot_id, self.pose, 0.0))
        return published_state.before_update(self.pose, self.config.robot, first)

    def set_manual(self, manual: bool) -> None:
        """Hand the robot to a person (True) or back to its strategy (False: it replans from
        where the person left it)."""
        with self._lock:
            if self.manual and not manual:
                self.goal = self.path = None
                self.velocity = self.heading = None
            self.manual = bool(manual)
            self._teleop = (0.0, 0.0, -math.inf)

    def set_region(self, region: Region) -> None:
        """Keep the importance density inside ``region`` (everywhere: the map's own density
        again). The strategy starts afresh on the restricted domain and the robot replans.
        ConfigError, and nothing changes, if the region holds no free space or the robot
        explores (its density is the belief's entropy)."""
        if self.belief is not None:
            raise ConfigError.at("region", "does not apply while exploring (the density is the "
                                 "belief's entropy)", region.describe())
        base = self._base_domain
        domain = base if region.everywhere else base.with_density(
            region.restrict(base.density, base.geometry, base.free))
        strategy = make_strategy(self.config.strategy,
                                 replace(self.strategy.context, domain=domain))
        with self._lock:
            self.domain, self.strategy, self.region = domain, strategy, region
            self.goal = self.path = None
            self.velocity = self.heading = None

    def set_paused(self, paused: bool) -> None:
        with self._lock:
            self.paused = bool(paused)

    def teleop(self, v: float, w: float, now: float) -> None:
        """A person's command (used while manual, until ``teleop_timeout`` passes)."""
        with self._lock:
            self._teleop = (float(v), float(w), now)

    def hold(self) -> None:
        """Stop following anything (e.g. after a failed update)."""
        with self._lock:
            self.path, self.velocity, self.heading = None, (0.0, 0.0), None

    def command(self, now: float, dt: float) -> tuple[float, float]:
        """One tracking period: the safe (v, w) to send."""
        with self._lock:
            return self._command(now, dt)

    def _command(self, now: float, dt: float) -> tuple[float, float]:
        if self.pose is None:
            return 0.0, 0.0
        pose = self.pose_ages.carried(self.pose, self.pose_stamp, self.tracker.v, self.tracker.w,
                                      now)
        limits = self.config.robot
        autonomous = not (self.paused or self.manual)
        escape = self.recovery.command(pose, now) if autonomous else None
        if self.recovery.ended:  # plan again from where the escape ended
            self._replan, self.recovery.ended = self.recovery.ended, ""
            self.goal = self.path = None
        if escape is not None:
            v, w = escape
        elif self.paused:
            v, w = 0.0, 0.0
        elif self.manual:
            v, w, heard = self._teleop
            if not 0.0 <= now - heard <= self.config.teleop_timeout:
                v, w = 0.0, 0.0  # the person let go (or the clock went back)
            v = float(np.clip(v, -limits.v_max, limits.v_max))
            w = float(np.clip(w, -limits.w_max, limits.w_max))
        elif self.velocity is not None:
            v, w = self.velocity
            if self.heading is not None:
                # Re-steer towards the strategy's heading every tracking period: a turn rate
                # held for a whole coverage period overshoots (and, saturated, spins).
                # The path tracker's own heading gain and turn-in-place angle: one way to steer.
                steer = self.tracker.config
                err = float(wrap_angle(self.heading - pose[2]))
                w = steer.heading_gain * err
                v = 0.0 if abs(err) > steer.turn_in_place else min(v, limits.v_max * math.cos(err))
            v = float(np.clip(v, -limits.v_max, limits.v_max))
            w = float(np.clip(w, -limits.w_max, limits.w_max))
        else:
            v, w, _ = self.tracker.command(pose, self.path, dt)
        positions, radii, velocities = safety_discs(self.neighbours.current(now), now,
                                                    self.config.robot)
        wanted = v
        v, w, self.safety_note = self.safety.filter(pose, v, w, positions, radii,
                                                    self.scan_points, velocities)
        if escape is not None:
            self.safety_note = self.recovery.describe() + \
                (f"; {self.safety_note}" if self.safety_note else "")
        elif autonomous:
            self.recovery.observe(wanted, v, self.safety_note, pose, now,
                                  lambda: self.safety.obstacles_near(pose, ESCAPE_LOOK,
                                                                     self.scan_points))
        self.tracker.override(v, w)
        self.sent = (v, w)
        return v, w

    def motion_state(self) -> dict[str, float]:
        """``vx``, ``vy`` of the last command sent (:func:`.published_state.motion`)."""
        return published_state.motion(self.sent, self.pose)

    def describe_pose_age(self) -> str:
        """One line on how old the poses were when commands were computed ('' if unknown)."""
        return self.pose_ages.describe()

    def describe(self) -> list[str]:
        """Lines for the log at the end: the last decision, and the poses' ages."""
        n, g = self.recovery.escapes, self.recovery.give_ways
        escapes = f"backed off {n} time(s) after being held still (recovery)" if n else ""
        gave = f"gave way to a robot ahead {g} time(s)" if g else ""
        return [text for text in (self.describe_last(), self.describe_pose_age(), escapes,
                                  gave, *self.strategy.describe()) if text]

    def describe_last(self) -> str:
        """One line on the last decision (mode, target, path, safety), '' before the first."""
        if self.last is None or self.pose is None:
            return ""
        d = self.last.decision
        goal = "none" if d.target is None else f"({d.target[0]:.2f}, {d.target[1]:.2f})"
        path = "no path" if self.path is None else f"path of {len(self.path)} points"
        return (f"last decision: mode {d.mode or '-'}, heading for {goal} ({path}) from "
                f"({self.pose[0]:.2f}, {self.pose[1]:.2f}); safety: {self.safety_note or 'clear'}")
