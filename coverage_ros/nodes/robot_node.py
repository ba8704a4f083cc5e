"""robot_node: one robot of a decentralized coverage team.

Runs in the robot's namespace (``/robot_<id>``). It knows the map (from ``/map`` or a file), its
own pose and scan, and what its neighbours publish; it finds its neighbours itself from the ROS
graph (every ``/robot_<k>/coverage_state`` topic), so no team list is configured and robots may
join or vanish at any time. Every coverage period it computes its own cell with the chosen
strategy, publishes ``goal_pose``, ``plan``, ``cell`` and ``coverage_state``; every tracking
period it sends a safe ``cmd_vel``. With ``drive: false`` it sends no ``cmd_vel``: the goal goes
to the robot's own navigator (Nav2's ``goal_pose``), only when it moved
(:mod:`~coverage_ros.core.control.goal_relay`). README "Robot node": parameters, topics.

Coverage updates run on a worker thread, so that tracking, the safety filter and incoming
messages never wait for them; they cost in proportion to the own cell (large in a team still
bunched up) and are spaced out to keep within ``update_load`` of a core (container: pooled).
With ``lockstep: true`` the world's ticks drive the robot instead of its timers, and every
input is used at the tick it belongs to (:mod:`~coverage_ros.nodes.robot_lockstep`).

    ros2 run coverage_ros robot_node --ros-args -r __ns:=/robot_3 -p robot_id:=3 \\
        -p use_sim_time:=true -p strategy:=geodesic
"""

from __future__ import annotations

import math
import sys
import time

from coverage_msgs.msg import RobotState
from nav_msgs.msg import OccupancyGrid, Odometry
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from coverage_ros.core.control.controller import RobotController
from coverage_ros.core.control.listening import TeamListening
from coverage_ros.core.control.pose_history import PoseHistory
from coverage_ros.core.exploration.belief import Belief
from coverage_ros.errors import ConfigError, CoverageError
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.belief_exchange import BeliefExchange
from coverage_ros.nodes.clock_guard import ClockGuard
from coverage_ros.nodes.lockstep_member import LockstepDriver
from coverage_ros.nodes.neighbour_input import NeighbourInput
from coverage_ros.nodes.parameters import declare_parameters
from coverage_ros.nodes.qos import MAP_QOS, TEAM_QOS
from coverage_ros.nodes.robot_config import load_robot_inputs
from coverage_ros.nodes.robot_lockstep import RobotLockstep
from coverage_ros.nodes.robot_output import RobotOutput
from coverage_ros.nodes.robot_parameters import PARAMETERS
from coverage_ros.nodes.robot_requests import RobotRequests
from coverage_ros.nodes.robot_shared import SharedInputs
from coverage_ros.nodes.runner import FatalConfigError, run_node
from coverage_ros.nodes.scan_input import ScanInput
from coverage_ros.nodes.tf_input import TfPoseInput
from coverage_ros.nodes.throttle import WarnThrottle
from coverage_ros.nodes.update_worker import UpdateWorker

DISCOVERY_PERIOD = 1.0  # [s] wall time between looks at the ROS graph for new neighbours
#: [s] wall time a robot listens for neighbours after its first pose before its first update
#: (one look at the ROS graph and their states), so that it does not start with the whole map;
#: with team_size until it heard them all (core/control/listening.py).
LISTEN_FIRST = DISCOVERY_PERIOD + 0.5


class RobotNode(Node):
    """See module docstring."""

    def __init__(self, cli_args: list[str] | None = None,
                 shared: SharedInputs | None = None, hub: bool = False) -> None:
        """``cli_args``: this node's own ROS arguments (namespace, parameters) when several
        share a process; ``shared``: what the robots of the process share; ``hub``: the
        process's :class:`StateHub` delivers the neighbours' states (no subscriptions here)."""
        super().__init__("coverage_robot", cli_args=cli_args)
        self.shared = shared if shared is not None else SharedInputs()
        inputs = load_robot_inputs(declare_parameters(self, PARAMETERS), self.get_namespace(),
                                   self.shared.world)
        self.config = inputs.config
        cc = self.config.controller
        self.frames = conv.RobotFrames.of(self.config.robot_prefix, cc.robot_id)
        self.controller: RobotController | None = None
        self._density = inputs.density
        self._world = inputs.world
        self._throttle = WarnThrottle(self.get_logger().warning)
        self._warn = self._throttle.warn  # (key, text)
        self._last_tick: float | None = None  # [s] the last tracking tick
        # Before the first update: listen for the team (wall time, as discovery runs).
        team = self.config.team_size
        self._listen = TeamListening(LISTEN_FIRST, team, self.config.listen_timeout)
        self._pose_stamp = -math.inf  # [s] stamp of the last pose taken from pose_topic
        self._last_state = -math.inf
        self.tick_time: float | None = None  # [s] lock-step: the tick being worked on
        self.lockstep = RobotLockstep(self) if self.config.lockstep else None
        self.neighbours = NeighbourInput(self, self.config.robot_prefix, team, not hub,
                                         self._on_state, lambda: self.exchange,
                                         self.lockstep is not None)

        self.output = RobotOutput(self, self.config, self.frames, self._warn)
        if self.config.pose_source == "tf":  # map -> base_link, as AMCL or slam_toolbox give it
            self.tf_input = TfPoseInput(self, self.frames, self._take_pose, self._warn)
        else:
            self.create_subscription(Odometry, self.config.pose_topic, self._on_pose, TEAM_QOS)
        self.requests = RobotRequests(self, cc.robot_id, self.config.teleop_topic,
                                      self.config.drive, self.config.region, self.output.goals,
                                      lambda: self.controller, self._now, self._warn)
        self.scans: ScanInput | None = None  # the lidar, once the controller needs it
        self.exchange: BeliefExchange | None = None
        self.poses = PoseHistory()  # scans are placed from these (safety, belief)
        if self.config.explore is not None:
            self._build(self.config.explore.lattice, Belief(self.config.explore.lattice,
                                                            cc.robot_id))
        elif self.config.map_free is not None:
            self._build(self.config.map_free)  # the area, every cell free: the lidar decides
        elif self.config.map_topic:
            self.create_subscription(OccupancyGrid, self.config.map_topic, self._on_map, MAP_QOS)
        elif inputs.world is not None:
            self._build(inputs.world.grid)
        else:
            raise ConfigError.at("map_topic", "is empty and no 'world' gives the map", "")
        wall = Clock(clock_type=ClockType.STEADY_TIME)
        if self.get_parameter("use_sim_time").value:
            self._clock_guard = ClockGuard()
            self.create_timer(1.0, self._check_clock, clock=wall)
        self._worker: UpdateWorker | None = None
        if self.lockstep is not None:  # the ticks drive it; neighbours come with the ticks
            if not hub:
                self.lockstep.driver = LockstepDriver(self, [self.lockstep], self._warn)
        else:
            self.create_timer(DISCOVERY_PERIOD, self.neighbours.discover, clock=wall)
            self._worker = UpdateWorker(
                self._update, self.config.update_load, slots=self.shared.update_slots,
                pool=self.shared.update_pool, clock=self._now,
                on_error=lambda exc: self._warn("update", f"coverage update failed: {exc!r}"))
            self.create_timer(1.0 / self.config.control_rate, self._on_control)
            self.create_timer(1.0 / self.config.tracking_rate, self._on_tracking)
        source = ("exploring (no map)" if self.config.explore is not None
                  else "map-free (lidar only)" if self.config.map_free is not None
                  else f"map from {self.config.map_topic or self.config.world}")
        if self.config.manual:
            source += f"; manual, driven by {self.config.teleop_topic}"
        if self.config.pose_source == "tf":
            source += f"; pose from /tf ({conv.MAP_FRAME} -> {self.frames.base_link})"
        if self.lockstep is not None:
            source += "; lock-step"
        self.get_logger().info(f"robot {cc.robot_id}: strategy {cc.strategy.name}, {source}; "
                               f"{cc.robot.describe()}")

    # ------------------------------------------------------------------ set-up
    def _build(self, grid, belief: Belief | None = None) -> None:
        t0 = time.perf_counter()
        # The world's travel metric on whatever lattice the map came on (exploring: the
        # entropy metric of the strategy instead).
        metric = self._world.metric if self._world is not None else None
        domain = self.shared.domain(grid, self.config.controller.robot.radius, self._density,
                                    self.config.connectivity, belief is not None,
                                    None if belief is not None else metric)
        self.controller = RobotController(domain, self.config.controller, belief)
        self.requests.apply(self.controller, self.config.manual)
        if belief is not None and self.config.explore is not None:
            self.exchange = BeliefExchange(
                self, belief, self.config.explore, self._throttle, self._now,
                None if self.lockstep is None else self.lockstep.put_evidence)
        if (self.config.use_scan or self.controller.needs_scan) and self.scans is None:
            self.scans = ScanInput(self, self.config.scan_topic)
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
        stamp = conv.from_time_msg(msg.header.stamp)
        problem = (conv.stamp_problem(msg.header.stamp)
                   or conv.quaternion_problem(msg.pose.pose.orientation)
                   or (None if all(math.isfinite(v) for v in pose) else f"{pose} is not finite")
                   or (None if stamp >= self._pose_stamp else f"stamp {stamp:.3f} s is older "
                       f"than the last pose's ({self._pose_stamp:.3f} s)"))
        if problem is not None:
            self._warn("pose", f"dropped a pose on {self.config.pose_topic}: {problem}")
            return
        self._pose_stamp = stamp
        self._take_pose(pose, stamp)

    def _take_pose(self, pose, stamp: float) -> None:
        """The robot's pose in the map frame at ``stamp`` [s] (from pose_topic or /tf)."""
        if self.controller is None:
            return
        if self.lockstep is not None:
            self.lockstep.put_pose(round(stamp * 1e9), pose)
            return
        self.controller.set_pose(pose, stamp)
        self._listen.pose(time.monotonic())
        self.poses.add(stamp, pose)
        if self.exchange is not None and self.scans is not None:
            self.scans.map_waiting()

    @property
    def uses_scan(self) -> bool:
        return self.scans is not None

    @property
    def robot_id(self) -> int:
        return self.config.controller.robot_id

    def _on_state(self, robot_id: int, msg: RobotState) -> None:
        try:
            values = conv.coverage_state_values(msg)
        except ValueError as exc:
            self._warn(f"state{robot_id}", f"dropped coverage_state of robot {robot_id}: {exc}")
            return
        self.take_state(robot_id, values, stamp=conv.stamp_ns(msg.header.stamp))

    def take_state(self, robot_id: int, values: dict[str, float],
                   parsed: dict | None = None, stamp: int = 0) -> None:
        """A neighbour's coverage_state stamped ``stamp`` [ns] (from this node's subscription
        or the hub, which passes its ``parsed``: see ``NeighbourTable.receive``)."""
        if self.lockstep is not None:
            self.lockstep.put_state(robot_id, stamp, values)
            return
        if self.controller is None:
            return
        why = self.controller.neighbours.receive(robot_id, values, self._now(), parsed)
        if why:
            self._warn(f"state{robot_id}", f"dropped coverage_state of robot {robot_id}: {why}")

    # ------------------------------------------------------------------ loops
    def _check_clock(self) -> None:
        """A second simulation on this domain would mix two teams: say so and stop."""
        error = self._clock_guard.check_publishers(self.count_publishers("/clock")) or \
            self._clock_guard.check_time(self._now())
        if error:
            raise FatalConfigError(f"robot {self.config.controller.robot_id}: {error}")

    def _now(self) -> float:
        if self.tick_time is not None:
            return self.tick_time
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_control(self) -> None:
        if self.controller is None:
            return
        listening, warning = self._listen.listening(
            time.monotonic(), len(self.controller.neighbours.entries))
        if warning:
            self.get_logger().warning(warning)
        if not listening and self._worker is not None:
            self._worker.request(self._now())

    def _update(self, now: float) -> None:
        """One coverage update and its messages (on the worker thread)."""
        c = self.controller
        if c is None:
            return
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
            self.output.update(c, result, now)
        except Exception:
            if self.context.ok():  # shutting down mid-publish is not an error
                raise

    def _on_tracking(self) -> None:
        c = self.controller
        if c is None or c.pose is None:
            return
        now = self._now()
        dt = 1.0 / self.config.tracking_rate if self._last_tick is None else \
            min(max(now - self._last_tick, 0.0), 0.5)
        self._last_tick = now
        if self.config.drive:
            v, w = c.command(now, dt)
            self.publish_cmd(v, w, now)
        if now - self._last_state >= 0.999 / self.config.state_rate:
            self._last_state = now
            self.publish_state(now, conv.to_time_msg(now))

    def publish_state(self, now: float, stamp, extra: dict[str, float] | None = None) -> None:
        """``coverage_state`` now (drive: false: the velocity from the poses); nothing before
        the robot has a pose."""
        c = self.controller
        if c is not None and c.pose is not None:
            motion = c.motion_state() if self.config.drive else self.poses.velocity()
            self.output.state(c, stamp, motion, extra)

    def publish_cmd(self, v: float, w: float, now: float, last: bool = False) -> None:
        self.output.command(v, w, now, last)

    def stop(self) -> None:
        """Best effort: finish the running update, leave the robot standing."""
        if self._worker is not None:
            self._worker.close()
            self.get_logger().info(self._worker.summary())
        driver = None if self.lockstep is None else self.lockstep.driver
        if driver is not None and driver.robots == [self.lockstep]:  # (a container's: its own)
            driver.close()
            self.get_logger().info(driver.summary())
        for text in self.controller.describe() if self.controller is not None else ():
            self.get_logger().info(text)
        if self.exchange is not None:
            self.get_logger().info(f"sent the evidence of {self.exchange.sent_cells} cells, "
                                   f"heard {len(self.exchange.heard)} robots")
        if self.context.ok():
            self.publish_cmd(0.0, 0.0, self._now(), last=True)


def main(args=None) -> int:
    return run_node("robot_node", RobotNode, args, cleanup=RobotNode.stop, parameters=PARAMETERS)


if __name__ == "__main__":
    sys.exit(main())
