"""The world node's transforms, REP 105 per robot (README "Using it on your robots"):

    map -> <prefix><id>/odom -> <prefix><id>/base_link -> <prefix><id>/base_scan

``odom -> base_link`` is the robot's odometry (with its noise) and ``map -> odom`` what makes
the chain end at the true pose, so the odometry's drift shows up in ``map -> odom`` as a
localizer's correction would; both on ``/tf`` at the odometry rate, while anyone listens.
``base_link -> base_scan`` (the lidar at the centre) is static: every robot's, in one message on
``/tf_static`` (transient local, sent again when a robot comes or goes, as tf2's static
broadcaster does).
"""

from __future__ import annotations

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from coverage_ros.core.control.frames import compose, invert
from coverage_ros.nodes import conversions as conv

TF_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
TF_STATIC_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)


class TfOutput:
    """See module docstring; ``available`` is False where tf2_msgs is not importable."""

    def __init__(self, node: Node) -> None:
        self.available = conv.TFMessage is not None
        self.frames: dict[int, conv.RobotFrames] = {}
        if not self.available:
            node.get_logger().warning("tf2_msgs is not importable: no /tf (scripts/bootstrap.sh "
                                      "builds it)")
            return
        self.pub = node.create_publisher(conv.TFMessage, "/tf", TF_QOS)
        self.static_pub = node.create_publisher(conv.TFMessage, "/tf_static", TF_STATIC_QOS)

    def set_robot(self, robot_id: int, frames: conv.RobotFrames | None, stamp) -> None:
        """A robot came (``frames``) or went (None): the static transforms again."""
        if frames is None:
            self.frames.pop(robot_id, None)
        else:
            self.frames[robot_id] = frames
        if self.available:
            self.static_pub.publish(conv.tf_message([
                conv.transform_msg(stamp, f.base_link, f.base_scan, (0.0, 0.0, 0.0))
                for _, f in sorted(self.frames.items())]))

    def publish(self, stamp, poses: dict[int, tuple[tuple, tuple]]) -> None:
        """``poses``: robot id -> (odometry pose in odom, true pose in map), ``(x, y, yaw)``."""
        if not self.available or not self.pub.get_subscription_count():
            return
        out = []
        for rid, (odom, truth) in poses.items():
            f = self.frames.get(rid)
            if f is None:
                continue
            out.append(conv.transform_msg(stamp, conv.MAP_FRAME, f.odom,
                                          compose(truth, invert(odom))))
            out.append(conv.transform_msg(stamp, f.odom, f.base_link, odom))
        if out:
            self.pub.publish(conv.tf_message(out))
