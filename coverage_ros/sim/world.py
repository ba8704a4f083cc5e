"""The simulated world: static geometry, robots, fixed-step physics and lidar scans (no rclpy).

Usage::

    world = World(load_world("config/worlds/office.yaml"), SimConfig(seed=1))
    world.populate(4)                        # start poses of the world, else a seeded cluster
    world.set_command(0, 0.2, 0.5)           # robot 0: v [m/s], w [rad/s]
    for _ in range(50):
        for scan in world.step():            # one physics step of 1 / physics_rate_hz
            ...                              # scans taken during that step

Everything is deterministic for a given seed: the same calls give the same trajectories and
scans. Separate random streams (spawned from the seed) serve placement, odometry noise and
lidar noise, so turning noise on does not move the robots' start poses.
"""

from __future__ import annotations

import atexit
import gc
import math
from dataclasses import dataclass

import numpy as np
import pymunk

from coverage_ros.core.world import LidarSpec, RobotSpec, WorldSpec, cluster_starts
from coverage_ros.core.world.placement import FreePlacer, check_pose
from coverage_ros.errors import ConfigError, WorldError
from coverage_ros.sim.lidar import SegmentIndex, cast_scans, finish_ranges, pymunk_scan
from coverage_ros.sim.robots import ROBOT_FRICTION, Robot
from coverage_ros.sim.static_geometry import StaticGeometry, build_static_geometry

COLLISION_SLOP = 0.0005  # [m] allowed resting overlap (pymunk's default 0.1 is meant for pixels)
# Fraction of an overlap left after one second: 1e-8 removes ~30 % per step at 50 Hz, so the
# transient overlap of an impact (at most one step of travel: 4.4 mm at 0.22 m/s and 50 Hz) is
# gone within ~10 steps (pymunk's default removes ~12 % per step).
COLLISION_BIAS = 1e-8
SOLVER_ITERATIONS = 10  # pymunk's default; enough for a few robots pushing each other
STATIC_TYPE = 1  # pymunk collision_type of walls and obstacles
ROBOT_TYPE = 2  # pymunk collision_type of robots
_GOLDEN = 0.6180339887498949  # spreads robot ids evenly over the scan groups
LIDAR_CASTERS = ("fast", "pymunk")

# A pymunk space with collision handlers sits in a reference cycle, so only the garbage collector
# frees it. Collect before interpreter teardown: a space freed after cffi is gone prints
# "extern Python ... not called in the current subinterpreter" warnings.
atexit.register(gc.collect)


@dataclass(frozen=True)
class SimConfig:
    """Simulation settings (the world node fills these from its parameters)."""

    seed: int = 0
    physics_rate_hz: float = 50.0  # [Hz] fixed physics steps per simulated second
    cmd_timeout: float = 0.5  # [s] sim time without a command after which a robot stops
    odom_noise_trans: float = 0.0  # [m/sqrt(m)] odometry translation random walk
    odom_noise_rot: float = 0.0  # [rad/sqrt(rad)] odometry heading random walk
    scan_noise_std: float | None = None  # [m] overrides every lidar's noise_std when set
    lidar_caster: str = "fast"  # "fast" (numpy) or "pymunk" (slow reference)
    # Robots scan in this many groups spread evenly over a scan period. Few groups let the
    # vectorized caster serve many robots per call.
    scan_groups: int = 2

    def __post_init__(self) -> None:
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError.at("seed", "must be an integer >= 0", self.seed)
        checks = (("physics_rate_hz", self.physics_rate_hz, 10.0, 10000.0),
                  ("cmd_timeout", self.cmd_timeout, 1e-6, math.inf),
                  ("odom_noise_trans", self.odom_noise_trans, 0.0, 10.0),
                  ("odom_noise_rot", self.odom_noise_rot, 0.0, 10.0))
        for name, value, lo, hi in checks:
            if (isinstance(value, bool) or not isinstance(value, int | float)
                    or math.isnan(value) or not lo <= value <= hi):
                raise ConfigError.at(name, f"must be a number in [{lo:g}, {hi:g}]", value)
        if self.scan_noise_std is not None and not 0 <= self.scan_noise_std < math.inf:
            raise ConfigError.at("scan_noise_std", "must be a finite number >= 0",
                                 self.scan_noise_std)
        if (isinstance(self.scan_groups, bool) or not isinstance(self.scan_groups, int)
                or self.scan_groups < 1):
            raise ConfigError.at("scan_groups", "must be an integer >= 1", self.scan_groups)
        if self.lidar_caster not in LIDAR_CASTERS:
            raise ConfigError.at("lidar_caster", "unknown caster", self.lidar_caster,
                                 f"one of {LIDAR_CASTERS}")

    @property
    def dt(self) -> float:
        """[s] physics step."""
        return 1.0 / self.physics_rate_hz


@dataclass(frozen=True)
class Scan:
    """One lidar scan: ``ranges`` ``(B,) float32`` [m] in REP 117 convention (see lidar.py),
    taken at sim time ``stamp`` [s] from true pose ``pose`` ``(x, y, yaw)``."""

    robot_id: int
    stamp: float
    ranges: np.ndarray
    pose: tuple[float, float, float]


@dataclass(frozen=True)
class Contact:
    """A robot's body began to touch something: a ``"wall"`` (static geometry) or a
    ``"robot"``, at sim time ``time`` [s], the robot at ``position`` (x, y) [m]."""

    time: float
    robot_id: int
    kind: str
    position: tuple[float, float]


#: Contacts kept for :meth:`World.take_contacts` (the oldest are dropped beyond this).
CONTACTS_KEPT = 256


class World:
    """A pymunk world of one :class:`WorldSpec` with any number of robots."""

    def __init__(self, spec: WorldSpec, config: SimConfig | None = None) -> None:
        self.spec = spec
        self.config = config or SimConfig()
        place_ss, odom_ss, scan_ss = np.random.SeedSequence(self.config.seed).spawn(3)
        self.rng_place = np.random.default_rng(place_ss)
        self.rng_odom = np.random.default_rng(odom_ss)
        self.rng_scan = np.random.default_rng(scan_ss)
        self.time = 0.0  # [s] sim time
        self.steps = 0
        self.robots: dict[int, Robot] = {}
        self.geometry: StaticGeometry = build_static_geometry(spec)
        self.index = SegmentIndex(self.geometry.segments)
        self.space = pymunk.Space()
        self.space.gravity = (0.0, 0.0)
        self.space.collision_slop = COLLISION_SLOP
        self.space.collision_bias = COLLISION_BIAS
        self.space.iterations = SOLVER_ITERATIONS
        self._add_static(self.geometry)
        self._owner: dict[pymunk.Shape, int] = {}
        self._contacts: list[Contact] = []
        self.space.on_collision(ROBOT_TYPE, STATIC_TYPE, begin=self._on_wall_contact)
        self.space.on_collision(ROBOT_TYPE, ROBOT_TYPE, begin=self._on_robot_contact)
        self._placer = FreePlacer(spec)
        self._next_group = 1

    # ------------------------------------------------------------------ set-up
    def _add_static(self, geom: StaticGeometry) -> None:
        body = self.space.static_body
        shapes: list[pymunk.Shape] = []
        for poly in geom.convex_polygons:
            shapes.append(pymunk.Poly(body, [tuple(p) for p in poly]))
        for cx, cy, r in geom.circles:
            shapes.append(pymunk.Circle(body, float(r), (float(cx), float(cy))))
        for ax, ay, bx, by in geom.physics_segments:
            shapes.append(pymunk.Segment(body, (float(ax), float(ay)), (float(bx), float(by)),
                                         0.0))
        for s in shapes:
            s.collision_type = STATIC_TYPE
            s.friction = ROBOT_FRICTION
            s.elasticity = 0.0
        self.space.add(*shapes)
        self.static_shapes = shapes

    def populate(self, count: int) -> list[int]:
        """Add robots ``0 .. count-1`` at the world's start poses; the rest (or all, if the world
        has none) in a seeded compact cluster or at free places. Returns the ids."""
        if isinstance(count, bool) or not isinstance(count, int) or count < 0:
            raise ConfigError.at("num_robots", "must be an integer >= 0", count)
        starts = self.spec.starts
        ids = []
        if not starts and count > 0:
            specs = [self.spec.robot_spec(i) for i in range(count)]
            radius = max(s.radius for s in specs)
            poses = cluster_starts(self.spec.grid, count, radius, self.rng_place)
            for i in range(count):
                ids.append(self.add_robot(i, tuple(poses[i]), specs[i]).id)
            return ids
        for i in range(count):
            if i < len(starts):
                s = starts[i]
                ids.append(self.add_robot(i, (s.x, s.y, s.yaw), s.robot).id)
            else:
                ids.append(self.add_robot(i, None, self.spec.robot).id)
        return ids

    # ------------------------------------------------------------------ robots
    def free_id(self) -> int:
        """The smallest robot id not in use."""
        i = 0
        while i in self.robots:
            i += 1
        return i

    def add_robot(self, robot_id: int, pose: tuple[float, float, float] | None = None,
                  spec: RobotSpec | None = None) -> Robot:
        """Add a robot (``pose=None``: a random free place away from other robots).
        Raises :class:`WorldError` if the id is taken or the pose is not free."""
        if isinstance(robot_id, bool) or not isinstance(robot_id, int) or robot_id < 0:
            raise WorldError.at("id", "must be an integer >= 0", robot_id)
        if robot_id in self.robots:
            raise WorldError.at(f"robot {robot_id}", "id is already in use")
        spec = spec or self.spec.robot
        others = [(r.pose()[0], r.pose()[1], r.spec.radius) for r in self.robots.values()]
        if pose is None:
            pose = self._placer.place(spec.radius, others, self.rng_place)
        else:
            pose = check_pose(self.spec, tuple(float(v) for v in pose), spec.radius, others,
                                      f"robot {robot_id}: pose")
        robot = Robot(robot_id, spec, pose, group=self._next_group, collision_type=ROBOT_TYPE,
                      spawn_time=self.time)
        self._next_group += 1
        group = math.floor(((robot_id * _GOLDEN) % 1.0) * self.config.scan_groups)
        robot.next_scan_time = self.time + group / self.config.scan_groups / spec.lidar.rate_hz
        self.space.add(*robot.pymunk_objects)
        self._owner[robot.shape] = robot_id
        self.robots[robot_id] = robot
        return robot

    def remove_robot(self, robot_id: int) -> None:
        """Remove a robot; raises :class:`WorldError` if there is none with that id."""
        robot = self.robots.pop(robot_id, None)
        if robot is None:
            raise WorldError.at(f"robot {robot_id}", "no such robot",
                                expected=f"one of {sorted(self.robots)}")
        self.space.remove(*robot.pymunk_objects)
        self._owner.pop(robot.shape, None)

    def set_command(self, robot_id: int, v: float, w: float) -> None:
        """Command robot ``robot_id`` (KeyError if unknown, ValueError if not finite)."""
        self.robots[robot_id].set_command(v, w, self.time)

    # ------------------------------------------------------------------ stepping
    def step(self) -> list[Scan]:
        """Advance one physics step; return the scans whose time fell in it."""
        dt = self.config.dt
        for robot in self.robots.values():
            robot.apply_drive(self.time, dt, self.config.cmd_timeout)
        self.space.step(dt)
        self.steps += 1
        self.time = self.steps * dt
        noisy = self.config.odom_noise_trans > 0 or self.config.odom_noise_rot > 0
        rng = self.rng_odom if noisy else None
        for robot in self.robots.values():
            robot.after_step(rng, self.config.odom_noise_trans, self.config.odom_noise_rot)
        self._track_separation()
        due = [r for r in self.robots.values() if r.next_scan_time <= self.time + 1e-9]
        return self._scans(due) if due else []

    def _track_separation(self) -> None:
        """Update every robot's closest centre distance to another robot."""
        if len(self.robots) < 2:
            return
        robots = list(self.robots.values())
        P = np.array([r.body.position for r in robots])
        d = np.hypot(P[:, None, 0] - P[None, :, 0], P[:, None, 1] - P[None, :, 1])
        np.fill_diagonal(d, np.inf)
        for robot, nearest in zip(robots, d.min(axis=1), strict=True):
            if nearest < robot.min_separation:
                robot.min_separation = float(nearest)

    def run(self, seconds: float) -> list[Scan]:
        """Step for ``seconds`` of sim time; return all scans."""
        scans: list[Scan] = []
        for _ in range(round(seconds / self.config.dt)):
            scans.extend(self.step())
        return scans

    def _scans(self, due: list[Robot]) -> list[Scan]:
        """Scan with every robot in ``due`` (one vectorized cast per distinct lidar)."""
        for robot in due:
            period = 1.0 / robot.spec.lidar.rate_hz
            robot.next_scan_time += period
            if robot.next_scan_time <= self.time:  # rate above the physics rate: never burst
                robot.next_scan_time = self.time + period
            robot.scans += 1
        by_lidar: dict[LidarSpec, list[Robot]] = {}
        for robot in due:
            by_lidar.setdefault(robot.spec.lidar, []).append(robot)
        scans: list[Scan] = []
        for group in by_lidar.values():
            ranges = self.scan_ranges([r.id for r in group])
            scans.extend(Scan(r.id, self.time, ranges[j], r.pose()) for j, r in enumerate(group))
        return scans

    def scan_ranges(self, robot_ids: list[int], caster: str | None = None) -> np.ndarray:
        """``(K, B) float32`` [m] scans of robots ``robot_ids`` (all with the same lidar) from
        their current poses, noise included."""
        robots = [self.robots[i] for i in robot_ids]
        lidar = robots[0].spec.lidar
        poses = np.array([r.pose() for r in robots], dtype=np.float64).reshape(-1, 3)
        if (caster or self.config.lidar_caster) == "pymunk":
            raw = np.stack([pymunk_scan(self.space, poses[j, :2], poses[j, 2], lidar,
                                        pymunk.ShapeFilter(group=r.group))
                            for j, r in enumerate(robots)])
        else:
            circles, owner = self._circles({r.id: j for j, r in enumerate(robots)})
            raw = cast_scans(poses[:, :2], poses[:, 2], lidar, self.index, circles, owner)
        std = self.config.scan_noise_std
        std = lidar.noise_std if std is None else std
        return finish_ranges(raw, lidar, std, self.rng_scan)

    def _circles(self, rows: dict[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """``(C, 3)`` static circles plus every robot's disc, and ``(C,)`` the scan row each
        robot disc belongs to (``rows`` maps robot id -> row; -1 for the others)."""
        static = self.geometry.circles
        discs = [(*r.body.position, r.spec.radius) for r in self.robots.values()]
        owner = [rows.get(i, -1) for i in self.robots]
        circles = np.concatenate([static, np.array(discs, dtype=np.float64).reshape(-1, 3)])
        return circles, np.concatenate([np.full(len(static), -1), owner]).astype(np.int64)

    # ------------------------------------------------------------------ contacts
    def take_contacts(self) -> list[Contact]:
        """The contacts that began since the last call (at most ``CONTACTS_KEPT``)."""
        out, self._contacts = self._contacts, []
        return out

    def _contact(self, rid: int, kind: str) -> None:
        x, y = self.robots[rid].body.position
        self._contacts.append(Contact(self.time, rid, kind, (float(x), float(y))))
        del self._contacts[:-CONTACTS_KEPT]

    def _on_wall_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:
        for shape in arbiter.shapes:
            rid = self._owner.get(shape)
            if rid is not None:
                self.robots[rid].wall_collisions += 1
                self._contact(rid, "wall")

    def _on_robot_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:
        for shape in arbiter.shapes:
            rid = self._owner.get(shape)
            if rid is not None:
                self.robots[rid].robot_collisions += 1
                self._contact(rid, "robot")
