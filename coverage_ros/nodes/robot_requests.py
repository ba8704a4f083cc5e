"""What a person (or another node) asks of a robot node: teleop commands while manual, the
``set_manual`` and ``pause`` services, and the region of interest. A mixin of
:class:`coverage_ros.nodes.robot_node.RobotNode`, which owns ``controller``, ``config``,
``goals``, ``_paused``, ``_now`` and ``_warn``."""

from __future__ import annotations

import math

from geometry_msgs.msg import Twist

from coverage_ros.nodes import conversions as conv


class RobotRequests:
    def _on_teleop(self, msg: Twist) -> None:
        c = self.controller
        if c is None or not c.manual:
            return
        v, w = float(msg.linear.x), float(msg.angular.z)
        if not (math.isfinite(v) and math.isfinite(w)):
            self._warn("teleop", f"dropped a non-finite teleop command ({v}, {w}) on "
                       f"{self.config.teleop_topic}")
            return
        c.teleop(v, w, self._now())

    def _on_set_manual(self, request, response):
        c = self.controller
        if c is None:
            response.success, response.message = False, "no map yet"
            return response
        if request.data and not self.config.drive:
            response.success = False
            response.message = "drive is false: the robot's own navigator drives it"
            return response
        c.set_manual(bool(request.data))
        response.success = True
        response.message = ("manual: driven by " + self.config.teleop_topic if request.data
                            else "autonomous")
        self.get_logger().info(f"robot {self.config.controller.robot_id}: {response.message}")
        return response

    def _set_region(self, region) -> None:
        if self.controller is not None:  # else applied when the map comes (_build)
            self.controller.set_region(region)

    def _on_pause(self, request, response):
        self._paused = bool(request.data)
        if self.controller is not None:
            self.controller.set_paused(self._paused)
            self.goals.hold(conv.to_time_msg(self._now()), self.controller.pose, self._paused)
        response.success = True
        response.message = "paused" if self._paused else "resumed"
        self.get_logger().info(f"robot {self.config.controller.robot_id}: {response.message}")
        return response
