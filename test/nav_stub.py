"""A stand-in for a robot's own navigator (Nav2's bt_navigator) in tests of ``drive: false``.

    python test/nav_stub.py OUT.json ID [ID ...]

For each robot id it listens to ``/robot_<id>/goal_pose`` (geometry_msgs/PoseStamped) and
``/robot_<id>/ground_truth`` (nav_msgs/Odometry) and drives ``/robot_<id>/cmd_vel`` to the last
goal: turn towards it, then go straight at 0.18 m/s (an open world, no obstacles between), stop
within 5 cm. Every second it notes which other nodes publish on ``cmd_vel``; it keeps the
fastest ``vx``, ``vy`` each robot's ``coverage_state`` carried. On SIGINT or SIGTERM it writes
``{"goals": {id: [[t, x, y, yaw, frame], ...]}, "cmd_vel_publishers": {id: [node, ...]},
"state_speed": {id: m/s}}`` to OUT.json.
"""

from __future__ import annotations

import json
import math
import signal
import sys
import time

import rclpy
from coverage_msgs.msg import RobotState
from geometry_msgs.msg import PoseStamped, Twist
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions


def yaw_of(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class NavStub(Node):
    def __init__(self, ids: list[int]) -> None:
        super().__init__("nav_stub")
        self.ids = ids
        self.goals: dict[int, list] = {i: [] for i in ids}
        self.pose: dict[int, tuple[float, float, float]] = {}
        self.others: dict[int, set[str]] = {i: set() for i in ids}
        self.state_speed: dict[int, float] = {i: 0.0 for i in ids}
        self.cmd = {i: self.create_publisher(Twist, f"/robot_{i}/cmd_vel", 10) for i in ids}
        for i in ids:
            # Best effort: compatible with any publisher's reliability.
            self.create_subscription(PoseStamped, f"/robot_{i}/goal_pose",
                                     lambda m, i=i: self._on_goal(i, m), qos_profile_sensor_data)
            self.create_subscription(Odometry, f"/robot_{i}/ground_truth",
                                     lambda m, i=i: self._on_odom(i, m), qos_profile_sensor_data)
            self.create_subscription(RobotState, f"/robot_{i}/coverage_state",
                                     lambda m, i=i: self._on_state(i, m), qos_profile_sensor_data)
        self.create_timer(0.1, self._drive)
        self.create_timer(1.0, self._graph)

    def _on_goal(self, i: int, m: PoseStamped) -> None:
        p = m.pose.position
        self.goals[i].append([time.monotonic(), p.x, p.y, yaw_of(m.pose.orientation),
                              m.header.frame_id])

    def _on_odom(self, i: int, m: Odometry) -> None:
        p = m.pose.pose
        self.pose[i] = (p.position.x, p.position.y, yaw_of(p.orientation))

    def _on_state(self, i: int, m: RobotState) -> None:
        speed = math.hypot(m.vx, m.vy) if math.isfinite(m.vx) and math.isfinite(m.vy) else 0.0
        self.state_speed[i] = max(self.state_speed[i], speed)

    def _drive(self) -> None:
        for i in self.ids:
            if i not in self.pose or not self.goals[i]:
                continue
            x, y, yaw = self.pose[i]
            gx, gy = self.goals[i][-1][1:3]
            d = math.hypot(gx - x, gy - y)
            cmd = Twist()
            if d > 0.05:
                err = math.atan2(math.sin(math.atan2(gy - y, gx - x) - yaw),
                                 math.cos(math.atan2(gy - y, gx - x) - yaw))
                cmd.angular.z = max(-1.5, min(1.5, 2.0 * err))
                cmd.linear.x = 0.0 if abs(err) > 0.5 else min(0.18, d)
            self.cmd[i].publish(cmd)

    def _graph(self) -> None:
        for i in self.ids:
            for info in self.get_publishers_info_by_topic(f"/robot_{i}/cmd_vel"):
                if info.node_name != self.get_name():
                    self.others[i].add(f"{info.node_namespace}/{info.node_name}")


def main() -> int:
    out, ids = sys.argv[1], [int(v) for v in sys.argv[2:]]
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = NavStub(ids)
    stop = []
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    try:
        while not stop:
            rclpy.spin_once(node, timeout_sec=0.05)
    except ExternalShutdownException:
        pass
    with open(out, "w") as f:
        json.dump({"goals": node.goals,
                   "cmd_vel_publishers": {i: sorted(s) for i, s in node.others.items()},
                   "state_speed": node.state_speed}, f)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
