"""What a robot node publishes: each coverage update's ``cell``, ``cell_polygon``, ``plan`` and
goals (:class:`~coverage_ros.nodes.goal_output.GoalOutput`), its ``coverage_state`` and its
``cmd_vel`` (none with ``drive: false``: the robot's own navigator owns it)."""

from __future__ import annotations

from collections.abc import Callable

from coverage_msgs.msg import RobotState
from geometry_msgs.msg import PolygonStamped, Twist, TwistStamped
from nav_msgs.msg import OccupancyGrid, Path

from coverage_ros.core.control.controller import RobotController, UpdateResult
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.goal_output import GoalOutput
from coverage_ros.nodes.qos import LOCKSTEP_STATE_QOS, TEAM_QOS, quiet_publisher
from coverage_ros.nodes.robot_config import RobotNodeConfig
from coverage_ros.nodes.runner import LAST_WORDS


class RobotOutput:
    """The publishers of robot ``robot_id`` on ``node`` (``frames``: its frame names)."""

    def __init__(self, node, config: RobotNodeConfig, frames: conv.RobotFrames,
                 warn: Callable[[str, str], object]) -> None:
        self.config, self.frames, self.warn = config, frames, warn
        self.robot_id = config.controller.robot_id
        self.logger = node.get_logger()
        self.mode = ""  # the last update's decision mode (a change is logged)

        def publisher(msg_type, topic):
            return node.create_publisher(msg_type, topic, TEAM_QOS,
                                         event_callbacks=quiet_publisher())

        self.cmd_pub = publisher(TwistStamped if config.use_stamped_cmd_vel else Twist,
                                 "cmd_vel") if config.drive else None
        self.goals = GoalOutput(publisher, config.drive, config.goal_topic,
                                config.goal_resend_distance)
        self.plan_pub, self.cell_pub = publisher(Path, "plan"), publisher(OccupancyGrid, "cell")
        self.polygon_pub = publisher(PolygonStamped, "cell_polygon")
        self.state_pub = node.create_publisher(
            RobotState, "coverage_state", LOCKSTEP_STATE_QOS if config.lockstep else TEAM_QOS,
            event_callbacks=quiet_publisher())

    def update(self, c: RobotController, result: UpdateResult, now: float) -> None:
        """One coverage update's cell, goal and plan. The state goes out at ``state_rate``
        only, with this update's values from now on: every state message wakes every
        neighbour, so their number must not grow with the update rate."""
        stamp = conv.to_time_msg(now)
        d = result.decision
        if d.mode != self.mode and {"relocate", "make_way"} & {d.mode, self.mode}:
            where = "" if d.goal is None else f" for ({d.goal[0]:.2f}, {d.goal[1]:.2f})"
            self.logger.info(f"t {now:.1f} s: mode {self.mode or '-'} -> {d.mode}{where} from "
                             f"({result.pose[0]:.2f}, {result.pose[1]:.2f})")
        self.mode = d.mode
        self.cell_pub.publish(conv.cell_grid_msg(c.domain.geometry, d.cell, stamp))
        if d.cell_polygon is not None and len(d.cell_polygon):
            self.polygon_pub.publish(conv.polygon_msg(stamp, d.cell_polygon))
        if c.manual or c.paused:
            return  # a person drives it, or it holds: no goal or plan to show
        # Self-steering strategies (tangentbug) have no goal for the planner, but a target.
        self.goals.publish(stamp, d.target, result.pose)
        if result.path is not None:
            self.plan_pub.publish(conv.path_msg(stamp, result.path))
        elif d.goal is not None and d.velocity is None:
            self.warn("plan", f"no path to goal ({d.goal[0]:.2f}, {d.goal[1]:.2f})")

    def state(self, c: RobotController, stamp, motion: dict[str, float],
              extra: dict[str, float] | None = None) -> None:
        """The last update's values (before the first update, presence) with the position
        and ``motion`` (velocity) fresh for the neighbours' safety filters."""
        state = dict(c.last.state) if c.last is not None else c.presence_state()
        assert c.pose is not None  # (the node publishes no state before a pose)
        state.update(x=float(c.pose[0]), y=float(c.pose[1]), **motion, **(extra or {}))
        self.state_pub.publish(conv.coverage_state_msg(stamp, state, robot_id=self.robot_id))

    def command(self, v: float, w: float, now: float, last: bool = False) -> None:
        """``cmd_vel`` [m/s, rad/s] (``last``: the process ends next, it must arrive)."""
        if self.cmd_pub is None:
            return
        msg = conv.command_to_twist(v, w)
        if self.config.use_stamped_cmd_vel:
            msg = TwistStamped(twist=msg)
            msg.header.stamp = conv.to_time_msg(now)
            msg.header.frame_id = self.frames.base_link
        if last:  # (runner.LastWords)
            LAST_WORDS.publish(self.cmd_pub, msg)
        else:
            self.cmd_pub.publish(msg)
