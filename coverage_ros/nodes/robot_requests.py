"""What a person (or another node) asks of a robot node: teleop commands while manual, the
``set_manual`` and ``pause`` services, and the region of interest - a component of
:class:`coverage_ros.nodes.robot_node.RobotNode`, like its ``GoalOutput``. Requests that come
before the map are kept and applied when the robot's controller is built (:meth:`apply`)."""

from __future__ import annotations

import math
from collections.abc import Callable

from geometry_msgs.msg import Twist
from std_srvs.srv import SetBool

from coverage_ros.core.control.controller import RobotController
from coverage_ros.core.world.region import Region
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.goal_output import GoalOutput
from coverage_ros.nodes.qos import TEAM_QOS
from coverage_ros.nodes.region_input import RegionInput


class RobotRequests:
    """The robot's request endpoints on ``node`` (its ``teleop_topic``, ``set_manual``,
    ``pause``, the region topics); ``controller()`` is the robot's controller or None before
    the map, ``now()`` the node's time [s], ``warn(key, text)`` a throttled warning."""

    def __init__(self, node, robot_id: int, teleop_topic: str, drive: bool, region: Region,
                 goals: GoalOutput, controller: Callable[[], RobotController | None],
                 now: Callable[[], float], warn: Callable[[str, str], object]) -> None:
        self.node, self.robot_id = node, robot_id
        self.teleop_topic, self.drive = teleop_topic, drive
        self.goals, self.controller, self.now, self.warn = goals, controller, now, warn
        self.paused = False
        if teleop_topic:
            node.create_subscription(Twist, teleop_topic, self._on_teleop, TEAM_QOS)
        node.create_service(SetBool, "set_manual", self._on_set_manual)
        node.create_service(SetBool, "pause", self._on_pause)
        self.regions = RegionInput(node, self._set_region, warn, region)

    def apply(self, controller: RobotController, manual: bool) -> None:
        """A controller was just built: it starts ``manual`` or not, with what was asked."""
        controller.set_manual(manual)
        controller.set_paused(self.paused)
        if not self.regions.region.everywhere:
            controller.set_region(self.regions.region)  # heard before the map came

    def _on_teleop(self, msg: Twist) -> None:
        c = self.controller()
        if c is None or not c.manual:
            return
        v, w = float(msg.linear.x), float(msg.angular.z)
        if not (math.isfinite(v) and math.isfinite(w)):
            self.warn("teleop", f"dropped a non-finite teleop command ({v}, {w}) on "
                      f"{self.teleop_topic}")
            return
        c.teleop(v, w, self.now())

    def _on_set_manual(self, request: SetBool.Request, response: SetBool.Response
                       ) -> SetBool.Response:
        c = self.controller()
        if c is None:
            response.success, response.message = False, "no map yet"
            return response
        if request.data and not self.drive:
            response.success = False
            response.message = "drive is false: the robot's own navigator drives it"
            return response
        c.set_manual(bool(request.data))
        response.success = True
        response.message = ("manual: driven by " + self.teleop_topic if request.data
                            else "autonomous")
        self.node.get_logger().info(f"robot {self.robot_id}: {response.message}")
        return response

    def _set_region(self, region: Region) -> None:
        c = self.controller()
        if c is not None:  # else applied when the map comes (apply)
            c.set_region(region)

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response
                  ) -> SetBool.Response:
        self.paused = bool(request.data)
        c = self.controller()
        if c is not None:
            c.set_paused(self.paused)
            self.goals.hold(conv.to_time_msg(self.now()), c.pose, self.paused)
        response.success = True
        response.message = "paused" if self.paused else "resumed"
        self.node.get_logger().info(f"robot {self.robot_id}: {response.message}")
        return response
