"""world_node: the pymunk world simulator as a ROS 2 node (topics and parameters: README).

It owns the simulation clock: it steps :class:`~coverage_ros.sim.world.World` at a fixed physics
rate, paced against *wall* time by ``real_time_factor`` (0: as fast as possible) - or, with
``lockstep: true``, one ``lockstep_period`` at a time when every robot has answered the last
(:mod:`~coverage_ros.nodes.world_lockstep`) - and publishes ``/clock`` so that every other node
runs with ``use_sim_time``. Per robot ``<id>`` in namespace
``/robot_<id>`` it subscribes ``cmd_vel`` and publishes ``odom``, ``ground_truth`` and ``scan``.
Robots are added and removed at run time through ``/world/spawn`` and ``/world/remove``.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from functools import partial
from typing import Any

from coverage_msgs.msg import WorldStatus
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import OccupancyGrid, Odometry
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Int32, String

from coverage_ros.core.world import load_planar_world, load_team, parse_poses
from coverage_ros.errors import ConfigError, CoverageError
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.parameters import declare_parameters
from coverage_ros.nodes.qos import MAP_QOS, SCAN_QOS, TEAM_QOS, TICK_QOS, quiet_publisher
from coverage_ros.nodes.runner import run_node
from coverage_ros.nodes.tf_output import TfOutput
from coverage_ros.nodes.throttle import WarnThrottle
from coverage_ros.nodes.world_config import PARAMETERS, world_inputs
from coverage_ros.nodes.world_lockstep import WorldLockstep
from coverage_ros.sim.world import Scan, World
from coverage_ros.worlds import resolve_world_path

DEFAULT_NUM_ROBOTS = 4  # robots when the world lists no start poses
WARN_PERIOD = 2.0  # [s] wall time between repeats of a throttled warning (the sim's inputs)
TICK_BUDGET = 0.05  # [s] wall time one pacing tick may step before serving callbacks again
MAX_LAG = 0.25  # [s] sim time behind schedule before the pacer gives up catching up


@dataclass
class RobotIO:
    """One robot's ROS endpoints."""

    frames: conv.RobotFrames
    cmd_sub: Any
    odom_pub: Any
    truth_pub: Any
    scan_pub: Any
    odom_msg: Odometry = field(default_factory=Odometry)  # reused: building one costs ~60 us
    truth_msg: Odometry = field(default_factory=Odometry)


class WorldNode(Node):
    """The world simulator node (see module docstring)."""

    def __init__(self) -> None:
        super().__init__("world")
        inputs = world_inputs(declare_parameters(self, PARAMETERS))
        self.config = inputs.config
        starts_text, team_path = inputs.starts, inputs.team
        self.spec = load_planar_world(resolve_world_path(self.config.world), "world")
        self.sim = World(self.spec, self.config.sim)
        count = self.config.num_robots
        if count < 0:
            count = len(self.spec.starts) or DEFAULT_NUM_ROBOTS
        self.io: dict[int, RobotIO] = {}
        self._throttle = WarnThrottle(self.get_logger().warning, WARN_PERIOD)
        self.clock_pub = self.create_publisher(Clock, "/clock", TEAM_QOS)
        self.map_pub = self.create_publisher(OccupancyGrid, "/map", MAP_QOS)
        self.status_pub = self.create_publisher(WorldStatus, "/world/robots", TEAM_QOS)
        self.tf = TfOutput(self) if self.config.publish_tf else None
        self.create_subscription(String, "/world/spawn", self._on_spawn, TEAM_QOS)
        self.create_subscription(Int32, "/world/remove", self._on_remove, TEAM_QOS)
        if team_path:
            for member in load_team(team_path, self.spec):
                self.sim.add_robot(member.id, member.start, member.spec)
                self._open_io(member.id)
        elif starts_text:
            poses = parse_poses(starts_text, "starts")
            if self.config.num_robots < 0:
                count = len(poses)
            if count > len(poses):
                raise ConfigError.at("starts", f"gives {len(poses)} poses for num_robots {count}",
                                     starts_text)
            for i in range(count):
                self.sim.add_robot(i, (float(poses[i][0]), float(poses[i][1]), float(poses[i][2])),
                                   self.spec.robot_spec(i))
                self._open_io(i)
        else:
            for robot_id in self.sim.populate(count):
                self._open_io(robot_id)
        if self.config.publish_map:
            self.map_pub.publish(conv.grid_to_occupancy_grid(self.spec.grid,
                                                             conv.to_time_msg(0.0)))
        self.publish_clock()
        dt = self.config.sim.dt
        self._next_odom = 0.0
        self._next_clock = 0.0
        rtf = self.config.real_time_factor
        self._anchor = (time.monotonic(), self.sim.time)  # (wall, sim) pacing reference
        self._rate_ref = self._anchor
        mode = f"real_time_factor {rtf:g}"
        self.lockstep = None
        if self.config.lockstep is not None:
            self.lockstep = WorldLockstep(self, self.config.lockstep)
            mode = (f"lock-step every {self.config.lockstep.period:g} s"
                    + (f", at most {rtf:g}x real time" if rtf > 0 else ""))
        else:
            period = min(max(dt / rtf, 0.001), 0.02) if rtf > 0 else 0.0005
            self.create_timer(period, self._on_tick)
            self.create_timer(1.0 / self.config.status_rate_hz, self.publish_status)
        self.get_logger().info(
            f"world '{self.spec.name}' ({self.config.world}) with {len(self.sim.robots)} robots, "
            f"physics {self.config.sim.physics_rate_hz:g} Hz, {mode}")

    # ------------------------------------------------------------------ helpers
    def _warn(self, key: str, text: str) -> None:
        self._throttle.warn(key, text)

    def _open_io(self, robot_id: int) -> None:
        frames = conv.RobotFrames.of(self.config.robot_prefix, robot_id)
        if self.config.use_stamped_cmd_vel:
            sub = self.create_subscription(
                TwistStamped, frames.topic("cmd_vel"),
                partial(self._on_stamped_cmd_vel, robot_id), TEAM_QOS)
        else:
            sub = self.create_subscription(
                Twist, frames.topic("cmd_vel"),
                partial(self._on_cmd_vel, robot_id), TEAM_QOS)
        # No QoS event handlers on per-robot publishers: rclpy's executor walks every handler
        # on every wake-up: 31 % -> 22 % CPU for 16 robots at real time (subscribers
        # still report incompatible QoS).
        self.io[robot_id] = RobotIO(
            frames, sub,
            self.create_publisher(Odometry, frames.topic("odom"), TEAM_QOS,
                                  event_callbacks=quiet_publisher()),
            self.create_publisher(Odometry, frames.topic("ground_truth"), TEAM_QOS,
                                  event_callbacks=quiet_publisher()),
            self.create_publisher(LaserScan, frames.topic("scan"),
                                  SCAN_QOS if self.config.lockstep is None else TICK_QOS,
                                  event_callbacks=quiet_publisher()))
        if self.tf is not None:
            self.tf.set_robot(robot_id, frames, conv.to_time_msg(self.sim.time))

    def _close_io(self, robot_id: int) -> None:
        io = self.io.pop(robot_id)
        if self.tf is not None:
            self.tf.set_robot(robot_id, None, conv.to_time_msg(self.sim.time))
        self.destroy_subscription(io.cmd_sub)
        for pub in (io.odom_pub, io.truth_pub, io.scan_pub):
            self.destroy_publisher(pub)

    # ------------------------------------------------------------------ callbacks
    def _on_stamped_cmd_vel(self, robot_id: int, msg: TwistStamped) -> None:
        self._on_cmd_vel(robot_id, msg.twist)

    def _on_cmd_vel(self, robot_id: int, twist: Twist) -> None:
        try:
            v, w = conv.twist_to_command(twist)
            self.sim.set_command(robot_id, v, w)
        except ValueError as exc:
            self._warn(f"cmd{robot_id}", f"robot {robot_id}: dropped cmd_vel: {exc}")
        except KeyError:
            pass  # removed while the message was in flight

    def _on_spawn(self, msg: String) -> None:
        try:
            req = conv.parse_spawn_request(msg.data, self.spec.robot)
            robot_id = self.sim.free_id() if req.robot_id is None else req.robot_id
            robot = self.sim.add_robot(robot_id, req.pose, req.robot)
        except CoverageError as exc:
            self._warn("spawn", f"dropped /world/spawn {msg.data!r}: {exc}")
            return
        self._open_io(robot_id)
        x, y, yaw = robot.pose()
        self.get_logger().info(f"spawned robot {robot_id} at ({x:.2f}, {y:.2f}, {yaw:.2f})")
        self.publish_status()

    def _on_remove(self, msg: Int32) -> None:
        try:
            self.sim.remove_robot(msg.data)
        except CoverageError as exc:
            self._warn("remove", f"dropped /world/remove {msg.data}: {exc}")
            return
        self._close_io(msg.data)
        self.get_logger().info(f"removed robot {msg.data}")
        if self.lockstep is not None:
            self.lockstep.robot_removed(msg.data)
        else:
            self.publish_status()

    # ------------------------------------------------------------------ stepping
    def _on_tick(self) -> None:
        """Step the physics as far as the pacing allows, for at most TICK_BUDGET wall time."""
        now = time.monotonic()
        dt = self.config.sim.dt
        rtf = self.config.real_time_factor
        deadline = now + TICK_BUDGET
        if rtf > 0:
            wall0, sim0 = self._anchor
            target = sim0 + (now - wall0) * rtf
            if target - self.sim.time > MAX_LAG:
                self._warn("lag", f"cannot keep real_time_factor {rtf:g}: running slower")
                self._anchor = (now, self.sim.time)
                target = self.sim.time + dt
            while (self.sim.time + 0.5 * dt <= target and time.monotonic() < deadline
                   and self.context.ok()):
                self._step()
        else:
            while time.monotonic() < deadline and self.context.ok():
                self._step()

    def _step(self) -> None:
        scans = self.sim.step()
        t = self.sim.time
        if t + 1e-9 >= self._next_clock:
            self.publish_clock()
            if self.config.clock_rate_hz > 0:
                self._next_clock = max(self._next_clock + 1.0 / self.config.clock_rate_hz, t)
        if t + 1e-9 >= self._next_odom:
            self.publish_odometry()
            self._next_odom = max(self._next_odom + 1.0 / self.config.odom_rate_hz, t)
        for scan in scans:
            self.publish_scan(scan)
        self.log_contacts()

    def log_contacts(self) -> None:
        for c in self.sim.take_contacts():
            self.get_logger().warning(
                f"robot {c.robot_id} touched {'a wall' if c.kind == 'wall' else 'a robot'} at "
                f"({c.position[0]:.2f}, {c.position[1]:.2f}), sim time {c.time:.2f} s")

    # ------------------------------------------------------------------ publishing
    def publish_clock(self) -> None:
        self.clock_pub.publish(conv.clock_msg(self.sim.time))

    def publish_odometry(self) -> None:
        stamp = conv.to_time_msg(self.sim.time)
        for robot_id, robot in self.sim.robots.items():
            io = self.io[robot_id]
            twist = robot.body_twist()
            odom = robot.odom
            # Nobody listening (coverage robots use ground_truth; a team has 2 x N of these
            # topics at 20 Hz): skip building the message.
            if io.odom_pub.get_subscription_count():
                io.odom_pub.publish(conv.odometry_msg(
                    stamp, io.frames.odom, io.frames.base_link, (odom.x, odom.y, odom.yaw),
                    twist, (odom.var_xy, odom.var_yaw), out=io.odom_msg))
            if io.truth_pub.get_subscription_count():
                io.truth_pub.publish(conv.odometry_msg(
                    stamp, conv.MAP_FRAME, io.frames.base_link, robot.pose(), twist,
                    out=io.truth_msg))
        if self.tf is not None:
            self.tf.publish(stamp, {rid: ((r.odom.x, r.odom.y, r.odom.yaw), r.pose())
                                    for rid, r in self.sim.robots.items()})

    def publish_scan(self, scan: Scan) -> LaserScan | None:
        """Publish ``scan``; the message, or None for a robot gone meanwhile."""
        io = self.io.get(scan.robot_id)
        robot = self.sim.robots.get(scan.robot_id)
        if io is None or robot is None:
            return None
        msg = conv.laser_scan_msg(scan.ranges, robot.spec.lidar, conv.to_time_msg(scan.stamp),
                                  io.frames.base_scan)
        io.scan_pub.publish(msg)
        return msg

    def publish_status(self) -> WorldStatus:
        now = time.monotonic()
        wall0, sim0 = self._rate_ref
        rtf = (self.sim.time - sim0) / (now - wall0) if now > wall0 else 0.0
        self._rate_ref = (now, self.sim.time)
        robots = []
        for robot_id, robot in self.sim.robots.items():
            x, y, yaw = robot.pose()
            robots.append({
                "id": robot_id, "x": x, "y": y, "yaw": yaw,
                "driving": self.sim.time - robot.last_cmd_time <= self.config.sim.cmd_timeout,
                "collisions": robot.collisions, "robot_collisions": robot.robot_collisions,
                "wall_collisions": robot.wall_collisions, "path_length": robot.path_length,
                "scans": robot.scans, "spawn_time": robot.spawn_time,
                "min_separation": robot.min_separation, **robot.spec.numbers(),
                "lidar_range_max": robot.spec.lidar.range_max})
        tick = self.lockstep.barrier.tick if self.lockstep is not None else 0
        msg = conv.world_status_msg(conv.to_time_msg(self.sim.time), self.spec.name, rtf,
                                    self.sim.steps, tick, robots)
        self.status_pub.publish(msg)
        return msg


def main(args=None) -> int:
    return run_node("world_node", WorldNode, args, parameters=PARAMETERS)


if __name__ == "__main__":
    sys.exit(main())
