"""robot_node: one robot of a decentralized coverage team.

Runs in the robot's namespace (``/robot_<id>``). It knows the map (from ``/map`` or a file), its
own pose and scan, and what its neighbours publish; it finds its neighbours itself from the ROS
graph (every ``/robot_<k>/coverage_state`` topic), so no team list is configured and robots may
join or vanish at any time. Every coverage period it computes its own cell with the chosen
strategy, publishes ``goal_pose``, ``plan``, ``cell`` and ``coverage_state``; every tracking
period it sends a safe ``cmd_vel``. See README "Robot node" for parameters and topics.

Coverage updates run on a worker thread, so that tracking, the safety filter and incoming
messages never wait for them; an update costs in proportion to the robot's own cell, which is
large while a team is still bunched up, so updates are spaced out to keep their CPU time
within ``update_load`` of one core (a robot far from its goal loses little by that).

    ros2 run coverage_ros robot_node --ros-args -r __ns:=/robot_3 -p robot_id:=3 \\
        -p use_sim_time:=true -p strategy:=geodesic
"""

from __future__ import annotations

import math
import re
import sys
import threading
import time
from dataclasses import dataclass, field

import numpy as np
import yaml
from geometry_msgs.msg import PolygonStamped, PoseStamped, Twist, TwistStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState, LaserScan

from coverage_ros.core.controller import ControllerConfig, RobotController
from coverage_ros.core.density import parse_density
from coverage_ros.core.domain import CoverageDomain
from coverage_ros.core.strategies import Scan
from coverage_ros.core.world import RobotSpec, load_world
from coverage_ros.errors import ConfigError, CoverageError
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.runner import (
    FatalConfigError,
    declare_parameters,
    quiet_publisher,
    quiet_subscription,
    run_node,
)
from coverage_ros.worlds import resolve_world_path

MAP_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                     reliability=ReliabilityPolicy.RELIABLE)
DISCOVERY_PERIOD = 1.0  # [s] wall time between looks at the ROS graph for new neighbours
#: [s] CPU time an update may borrow ahead of update_load (see UpdateWorker).
UPDATE_BURST = 1.0
#: [s] wall time a robot listens for neighbours after its first pose before its first update
#: (one look at the ROS graph and their states), so that it does not start with the whole map.
LISTEN_FIRST = DISCOVERY_PERIOD + 0.5
WARN_PERIOD = 5.0  # [s] wall time between two warnings of the same kind
STATE_TYPE = "sensor_msgs/msg/JointState"


_PARAMETERS = {  # name: (default, description)
    "robot_id": (-1, "this robot's id; -1: from the namespace /<robot_prefix><id>"),
    "strategy": ("geodesic", "coverage strategy: geodesic, lloyd, tangentbug, bvc, acvt"),
    "strategy_params": ("", "YAML mapping of strategy parameters, e.g. '{method: paper}'"),
    "world": ("", "world name or YAML: importance density (and the map when map_topic is '')"),
    "map_topic": ("/map", "nav_msgs/OccupancyGrid topic (transient local); '': map of 'world'"),
    "density": ("", "YAML importance density overriding the world's (default uniform)"),
    "robot_radius": (RobotSpec().radius, "[m] robot radius (inflates the map)"),
    "v_max": (RobotSpec().v_max, "[m/s] maximum linear speed"),
    "w_max": (RobotSpec().w_max, "[rad/s] maximum angular speed"),
    "a_max": (RobotSpec().a_max, "[m/s^2] linear acceleration limit"),
    "alpha_max": (RobotSpec().alpha_max, "[rad/s^2] angular acceleration limit"),
    "sensor_radius": (3.5, "[m] sensing radius (sensor-based strategies, coverage metrics)"),
    "power_weight": (0.0, "[m] power weight R of this robot (power Voronoi cells)"),
    "control_rate": (2.0, "[Hz] coverage updates (cell, goal, state), at most"),
    "update_load": (0.1, "largest fraction of one CPU core spent on coverage updates; "
                    "costly updates are spaced out to keep within it"),
    "tracking_rate": (10.0, "[Hz] path tracking and cmd_vel"),
    "state_rate": (2.5, "[Hz] coverage_state: the last update's values with the current "
                   "position (neighbours' tessellations and safety filters); at most "
                   "tracking_rate"),
    "comm_range": (0.0, "[m] neighbours farther than this are ignored; 0: no limit"),
    "neighbour_timeout": (2.0, "[s] a neighbour silent this long is ignored"),
    "pose_topic": ("ground_truth", "nav_msgs/Odometry with the robot pose in the map frame"),
    "scan_topic": ("scan", "sensor_msgs/LaserScan of the robot's lidar"),
    "use_scan": (True, "use the lidar in the safety filter (always on for sensor strategies)"),
    "use_stamped_cmd_vel": (False, "publish geometry_msgs/TwistStamped instead of Twist"),
    "goal_tolerance": (0.05, "[m] goal closer than this = arrived / converged"),
    "robot_prefix": ("robot_", "namespace prefix of the team's robots (neighbour discovery)"),
    "connectivity": (8, "grid graph neighbourhood: 8 (seed 000) or 16"),
}


@dataclass(frozen=True)
class RobotNodeConfig:
    controller: ControllerConfig
    world: str = ""
    map_topic: str = "/map"
    density: str = ""
    control_rate: float = 2.0
    update_load: float = 0.1
    tracking_rate: float = 10.0
    state_rate: float = 2.5
    pose_topic: str = "ground_truth"
    scan_topic: str = "scan"
    use_scan: bool = True
    use_stamped_cmd_vel: bool = False
    robot_prefix: str = "robot_"
    connectivity: int = 8
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("control_rate", "tracking_rate", "state_rate"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError.at(name, "must be a number > 0 [Hz]", v)
        if not (math.isfinite(self.update_load) and 0 < self.update_load <= 1):
            raise ConfigError.at("update_load", "must be a fraction in (0, 1]",
                                 self.update_load)
        if not self.map_topic and not self.world:
            raise ConfigError.at("map_topic", "is empty and no 'world' gives the map", "")
        if self.connectivity not in (8, 16):
            raise ConfigError.at("connectivity", "must be 8 or 16", self.connectivity)


def robot_id_from_namespace(namespace: str, prefix: str) -> int:
    m = re.fullmatch(rf"/{re.escape(prefix)}(\d+)", namespace)
    if not m:
        raise ConfigError.at("robot_id", f"not set and the namespace {namespace!r} is not "
                             f"/{prefix}<id>", -1, f"-p robot_id:=N or -r __ns:=/{prefix}N")
    return int(m.group(1))


class UpdateWorker:
    """Runs ``run(now)`` on its own thread when asked, one call at a time, and keeps the CPU
    time of the calls within ``load`` of one core on average.

    A CPU-time credit (a token bucket) grows by ``load`` per wall second up to ``burst``
    seconds and every call spends its CPU time; a call may start while the credit is not
    negative. So by any start time t, the calls before it used at most
    ``burst + load * (t - created)`` seconds of CPU, and a single costly call (the first,
    cold one, or one in a very large cell) is absorbed by the credit instead of holding back
    the next updates for c / load seconds. An exception raised by a call goes to ``on_error``
    and the worker carries on."""

    def __init__(self, run, load: float, on_error=None, burst: float = UPDATE_BURST) -> None:
        self._run = run
        self._on_error = on_error
        self._load = load
        self.burst = burst
        self._wake = threading.Event()
        self._closing = False
        self._busy = False
        self._now = 0.0
        self.created = time.monotonic()
        self._credit = burst  # [s] CPU time
        self._credit_at = self.created
        self.cpu_ms: list[float] = []  # CPU time of every call
        self.starts: list[float] = []  # [s] monotonic start of every call
        self._thread = threading.Thread(target=self._loop, name="coverage-update", daemon=True)
        self._thread.start()

    def request(self, now: float) -> bool:
        """Start a call for node time ``now``; False if one is running or it is too early."""
        if self._busy or self._closing or self._refill(time.monotonic()) < 0:
            return False
        self._busy, self._now = True, now
        self._wake.set()
        return True

    def _loop(self) -> None:
        while True:
            self._wake.wait()
            self._wake.clear()
            if self._closing:
                return
            start, cpu0 = time.monotonic(), time.thread_time()
            try:
                self._run(self._now)
            except Exception as exc:
                if self._on_error is not None:
                    self._on_error(exc)
            finally:
                cpu = time.thread_time() - cpu0
                self._refill(start)
                self._credit -= cpu
                self.cpu_ms.append(1e3 * cpu)
                self.starts.append(start)
                self._busy = False

    def _refill(self, now: float) -> float:
        if now > self._credit_at:
            self._credit = min(self.burst, self._credit + self._load * (now - self._credit_at))
            self._credit_at = now
        return self._credit

    def summary(self) -> str:
        """One line on the calls so far: count, mean period, CPU per call."""
        n = len(self.cpu_ms)
        if n == 0:
            return "no coverage updates"
        period = (self.starts[-1] - self.starts[0]) / (n - 1) if n > 1 else math.nan
        cpu = np.asarray(self.cpu_ms)
        return (f"{n} coverage updates, one every {period:.2f} s wall; CPU per update "
                f"median {np.median(cpu):.1f} ms, max {cpu.max():.1f} ms "
                f"(update_load {self._load:g})")

    def close(self, timeout: float = 5.0) -> None:
        """Stop the thread (waits for a running call up to ``timeout``)."""
        self._closing = True
        self._wake.set()
        self._thread.join(timeout)


class RobotNode(Node):
    """See module docstring."""

    def __init__(self) -> None:
        super().__init__("coverage_robot")
        p = declare_parameters(self, _PARAMETERS)
        self.config = self._config(p)
        cc = self.config.controller
        self.frames = conv.RobotFrames.of(self.config.robot_prefix, cc.robot_id)
        self.controller: RobotController | None = None
        self._density = None
        self._file_grid = None
        self._load_world_inputs()
        self._warned: dict[str, float] = {}
        self._subs: dict[int, object] = {}
        self._last_tick = None
        self._first_pose: float | None = None  # [s] monotonic
        self._last_state = -math.inf
        def publisher(msg_type, topic):
            return self.create_publisher(msg_type, topic, 10, event_callbacks=quiet_publisher())

        self.cmd_pub = publisher(TwistStamped if self.config.use_stamped_cmd_vel else Twist,
                                 "cmd_vel")
        self.goal_pub = publisher(PoseStamped, "goal_pose")
        self.plan_pub = publisher(Path, "plan")
        self.cell_pub = publisher(OccupancyGrid, "cell")
        self.polygon_pub = publisher(PolygonStamped, "cell_polygon")
        self.state_pub = publisher(JointState, "coverage_state")
        self.create_subscription(Odometry, self.config.pose_topic, self._on_pose, 10)
        self._scan_sub = None
        if self.config.map_topic:
            self.create_subscription(OccupancyGrid, self.config.map_topic, self._on_map, MAP_QOS)
        else:
            self._build(self._file_grid)
        wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(DISCOVERY_PERIOD, self._discover, clock=wall)
        self._worker = UpdateWorker(
            self._update, self.config.update_load,
            on_error=lambda exc: self._warn("update", f"coverage update failed: {exc!r}"))
        self.create_timer(1.0 / self.config.control_rate, self._on_control)
        self.create_timer(1.0 / self.config.tracking_rate, self._on_tracking)
        self.get_logger().info(
            f"robot {cc.robot_id}: strategy {cc.strategy}, map from "
            f"{self.config.map_topic or self.config.world}")

    # ------------------------------------------------------------------ configuration
    def _config(self, p: dict) -> RobotNodeConfig:
        prefix = p["robot_prefix"]
        rid = p["robot_id"] if p["robot_id"] >= 0 else robot_id_from_namespace(
            self.get_namespace(), prefix)
        params = {}
        if p["strategy_params"]:
            try:
                params = yaml.safe_load(p["strategy_params"]) or {}
            except yaml.YAMLError as exc:
                raise ConfigError.at("strategy_params", f"is not valid YAML ({exc})",
                                     p["strategy_params"]) from None
            if not isinstance(params, dict):
                raise ConfigError.at("strategy_params", "must be a YAML mapping",
                                     p["strategy_params"])
        robot = RobotSpec(radius=p["robot_radius"], v_max=p["v_max"], w_max=p["w_max"],
                          a_max=p["a_max"], alpha_max=p["alpha_max"])
        controller = ControllerConfig(
            robot_id=rid, strategy=p["strategy"], strategy_params=params, robot=robot,
            sensor_radius=p["sensor_radius"], power_weight=p["power_weight"],
            comm_range=p["comm_range"], neighbour_timeout=p["neighbour_timeout"],
            goal_tolerance=p["goal_tolerance"])
        return RobotNodeConfig(
            controller=controller, world=p["world"], map_topic=p["map_topic"],
            density=p["density"], control_rate=p["control_rate"],
            update_load=p["update_load"],
            tracking_rate=p["tracking_rate"], state_rate=p["state_rate"],
            pose_topic=p["pose_topic"],
            scan_topic=p["scan_topic"], use_scan=p["use_scan"],
            use_stamped_cmd_vel=p["use_stamped_cmd_vel"], robot_prefix=prefix,
            connectivity=p["connectivity"])

    def _load_world_inputs(self) -> None:
        if self.config.world:
            spec = load_world(resolve_world_path(self.config.world))
            self._density = spec.density
            self._file_grid = spec.grid
        if self.config.density:
            try:
                data = yaml.safe_load(self.config.density)
            except yaml.YAMLError as exc:
                raise ConfigError.at("density", f"is not valid YAML ({exc})",
                                     self.config.density) from None
            self._density = parse_density(data, "density")

    def _build(self, grid) -> None:
        t0 = time.perf_counter()
        domain = CoverageDomain.from_grid(grid, self.config.controller.robot.radius,
                                          self._density, connectivity=self.config.connectivity)
        self.controller = RobotController(domain, self.config.controller)
        if (self.config.use_scan or self.controller.needs_scan) and self._scan_sub is None:
            # Best effort and volatile: compatible with every publisher, no QoS events to watch.
            self._scan_sub = self.create_subscription(
                LaserScan, self.config.scan_topic, self._on_scan, qos_profile_sensor_data,
                event_callbacks=quiet_subscription())
        self.get_logger().info(f"map {grid.width} x {grid.height} cells at "
                               f"{grid.resolution:g} m ready in {time.perf_counter() - t0:.2f} s")

    # ------------------------------------------------------------------ inputs
    def _on_map(self, msg: OccupancyGrid) -> None:
        if self.controller is not None:
            return  # the map is static; a re-publication changes nothing
        try:
            grid = conv.occupancy_grid_to_grid(msg)
        except (CoverageError, ValueError) as exc:
            self._warn("map", f"dropped a map on {self.config.map_topic}: {exc}")
            return
        try:
            self._build(grid)
        except ConfigError as exc:
            raise FatalConfigError(str(exc)) from None

    def _on_pose(self, msg: Odometry) -> None:
        if self.controller is None:
            return
        if msg.header.frame_id != conv.MAP_FRAME:
            self._warn("pose", f"dropped a pose in frame {msg.header.frame_id!r} (expected "
                       f"{conv.MAP_FRAME!r}) on {self.config.pose_topic}")
            return
        pose = conv.odometry_to_pose(msg)
        if not all(math.isfinite(v) for v in pose):
            self._warn("pose", f"dropped a non-finite pose {pose} on {self.config.pose_topic}")
            return
        self.controller.set_pose(pose)
        if self._first_pose is None:
            self._first_pose = time.monotonic()

    def _on_scan(self, msg: LaserScan) -> None:
        c = self.controller
        if c is None or c.pose is None:
            return
        _, ranges = conv.laser_scan_to_ranges(msg)
        if len(ranges) == 0 or not math.isfinite(msg.angle_increment):
            self._warn("scan", "dropped an empty or malformed scan")
            return
        scan = Scan(ranges=ranges, angle_min=float(msg.angle_min),
                    angle_increment=float(msg.angle_increment), range_min=float(msg.range_min),
                    range_max=float(msg.range_max))
        c.set_scan(scan, conv.scan_to_points(msg, tuple(c.pose)))

    def _discover(self) -> None:
        """Subscribe to every new /<prefix><k>/coverage_state topic (k != own id)."""
        pattern = re.compile(rf"/{re.escape(self.config.robot_prefix)}(\d+)/coverage_state")
        for name, types in self.get_topic_names_and_types():
            m = pattern.fullmatch(name)
            if not m or STATE_TYPE not in types:
                continue
            rid = int(m.group(1))
            if rid == self.config.controller.robot_id or rid in self._subs:
                continue
            if self.count_publishers(name) == 0:
                continue  # only subscribers so far (e.g. a monitor): not a robot yet
            self._subs[rid] = self.create_subscription(
                JointState, name, lambda msg, rid=rid: self._on_state(rid, msg), 10,
                event_callbacks=quiet_subscription())
            self.get_logger().info(f"neighbour {rid} found on {name}")

    def _on_state(self, robot_id: int, msg: JointState) -> None:
        if self.controller is None:
            return
        try:
            values = conv.coverage_state_values(msg)
        except ValueError as exc:
            self._warn(f"state{robot_id}", f"dropped coverage_state of robot {robot_id}: {exc}")
            return
        why = self.controller.neighbours.receive(robot_id, values, self._now())
        if why:
            self._warn(f"state{robot_id}", f"dropped coverage_state of robot {robot_id}: {why}")

    # ------------------------------------------------------------------ loops
    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_control(self) -> None:
        if self.controller is None:
            return
        if self._first_pose is not None and time.monotonic() - self._first_pose < LISTEN_FIRST:
            return  # still listening for neighbours
        self._worker.request(self._now())

    def _update(self, now: float) -> None:
        """One coverage update and its messages (on the worker thread)."""
        c = self.controller
        try:
            result = c.update(now)
        except Exception as exc:  # a strategy bug must not take the robot down: stop instead
            if not self.context.ok():
                return
            self._warn("update", f"coverage update failed ({type(exc).__name__}: {exc}); "
                       "holding position")
            c.hold()
            return
        if result is None:
            self._warn("nopose", f"no pose yet on {self.config.pose_topic}")
            return
        try:
            self._publish_update(c, result, now)
        except Exception:
            if self.context.ok():  # shutting down mid-publish is not an error
                raise

    def _publish_update(self, c: RobotController, result, now: float) -> None:
        # The state goes out at state_rate only (_on_tracking), with this update's values from
        # now on: every state message wakes every neighbour, so their number must not grow
        # with the update rate.
        stamp = conv.to_time_msg(now)
        d = result.decision
        grid = c.domain.geometry
        self.cell_pub.publish(conv.cell_grid_msg(grid, d.cell, stamp))
        if d.cell_polygon is not None and len(d.cell_polygon):
            self.polygon_pub.publish(conv.polygon_msg(stamp, d.cell_polygon))
        # Self-steering strategies (tangentbug) have no goal for the planner, but a target.
        goal = d.goal if d.goal is not None else d.info.get("real_target")
        if goal is not None:
            self.goal_pub.publish(conv.pose_stamped_msg(stamp, goal[0], goal[1],
                                                        float(result.pose[2])))
        if result.path is not None:
            self.plan_pub.publish(conv.path_msg(stamp, result.path))
        elif d.goal is not None and d.velocity is None:
            self._warn("plan", f"no path to goal ({d.goal[0]:.2f}, {d.goal[1]:.2f})")

    def _on_tracking(self) -> None:
        c = self.controller
        if c is None or c.pose is None:
            return
        now = self._now()
        dt = 1.0 / self.config.tracking_rate if self._last_tick is None else \
            min(max(now - self._last_tick, 0.0), 0.5)
        self._last_tick = now
        v, w = c.command(now, dt)
        self._publish_cmd(v, w, now)
        if now < self._last_state:  # sim time went back (a restarted simulation)
            self._last_state = -math.inf
        if now - self._last_state >= 0.999 / self.config.state_rate:
            # The state with the current position between updates: neighbours' safety filters
            # need fresh positions (the coverage period is too slow for that). Before the first
            # update it has no mass or cost yet, but lets the neighbours see this robot.
            self._last_state = now
            state = dict(c.last.state) if c.last is not None else c.presence_state()
            state["x"], state["y"] = float(c.pose[0]), float(c.pose[1])
            self.state_pub.publish(conv.coverage_state_msg(conv.to_time_msg(now), state))

    def _publish_cmd(self, v: float, w: float, now: float) -> None:
        twist = conv.command_to_twist(v, w)
        if self.config.use_stamped_cmd_vel:
            msg = TwistStamped()
            msg.header.stamp = conv.to_time_msg(now)
            msg.header.frame_id = self.frames.base_link
            msg.twist = twist
            self.cmd_pub.publish(msg)
        else:
            self.cmd_pub.publish(twist)

    def stop(self) -> None:
        """Best effort: finish the running update, leave the robot standing."""
        self._worker.close()
        self.get_logger().info(self._worker.summary())
        if self.context.ok():
            self._publish_cmd(0.0, 0.0, self._now())

    def _warn(self, key: str, text: str) -> None:
        now = time.monotonic()
        if now - self._warned.get(key, -math.inf) >= WARN_PERIOD:
            self._warned[key] = now
            self.get_logger().warning(text)


def main(args=None) -> int:
    return run_node("robot_node", RobotNode, args, cleanup=RobotNode.stop)


if __name__ == "__main__":
    sys.exit(main())
