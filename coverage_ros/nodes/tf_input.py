"""A robot's pose from the transform tree (``robot_node`` with ``pose_source: tf``): the newest
``map <- base_link`` through whatever frames the robot's localization publishes (AMCL and
slam_toolbox: ``map -> odom``, the robot's driver: ``odom -> base_link``), from ``/tf`` and
``/tf_static`` (:class:`~coverage_ros.core.control.frames.FrameTree`). A pose is taken every time
a transform on the robot's own chain arrives; a malformed transform is dropped with a warning.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from coverage_ros.core.control.frames import FrameTree
from coverage_ros.errors import ConfigError
from coverage_ros.nodes import conversions as conv

TF_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
TF_STATIC_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)


class TfPoseInput:
    def __init__(self, node: Node, frames: conv.RobotFrames,
                 take: Callable[[tuple[float, float, float], float], None],
                 warn: Callable[[str, str], object]) -> None:
        if conv.TFMessage is None:
            raise ConfigError.at("pose_source", "is tf but tf2_msgs is not importable", "tf",
                                 "run scripts/bootstrap.sh (it builds tf2_msgs), or "
                                 "pose_source:=ground_truth")
        self.tree = FrameTree()
        self.base_link = frames.base_link
        self._take, self._warn = take, warn
        node.create_subscription(conv.TFMessage, "/tf", self._on_tf, TF_QOS)
        node.create_subscription(conv.TFMessage, "/tf_static",
                                 lambda m: self._on_tf(m, static=True), TF_STATIC_QOS)

    def _on_tf(self, msg, static: bool = False) -> None:
        good, dropped = conv.transforms_of(msg)
        if dropped:
            self._warn("tf", f"dropped {len(dropped)} transforms on "
                       f"{'/tf_static' if static else '/tf'}, e.g. {dropped[0]}")
        for parent, child, pose, stamp in good:
            try:
                self.tree.set(parent, child, pose, -math.inf if static else stamp)
            except ValueError as exc:
                self._warn("tf", f"dropped a transform on {'/tf_static' if static else '/tf'}: "
                           f"{exc}")
        found = self.tree.lookup(conv.MAP_FRAME, self.base_link)
        if found is not None:
            pose, stamp = found
            self._take(pose, stamp if math.isfinite(stamp) else 0.0)
