"""A robot node's lidar (``scan_topic``): each scan goes to the safety filter, placed from the
pose at its own stamp (:class:`~coverage_ros.core.control.pose_history.PoseHistory`), and,
exploring, into the belief once that pose is known
(:class:`~coverage_ros.core.control.pose_history.ScanPairing`). In lock-step a scan waits in the
robot's inbox for its tick. A malformed scan is dropped with a throttled warning."""

from __future__ import annotations

import math

from sensor_msgs.msg import LaserScan

from coverage_ros.core.control.pose_history import ScanPairing
from coverage_ros.core.strategies import Scan
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.qos import SCAN_QOS, TICK_QOS, quiet_subscription


class ScanInput:
    """``node`` is the :class:`~coverage_ros.nodes.robot_node.RobotNode` (its controller,
    poses, lockstep, exchange, ``_now`` and ``_warn``)."""

    def __init__(self, node, topic: str) -> None:
        self.node = node
        self.pairing = ScanPairing(node.poses)
        # Best effort and volatile: compatible with every publisher, no QoS events to watch
        # (lock-step: reliable, a tick waits for its scans).
        node.create_subscription(LaserScan, topic, self._on_scan,
                                 SCAN_QOS if node.lockstep is None else TICK_QOS,
                                 event_callbacks=quiet_subscription())

    def _on_scan(self, msg: LaserScan) -> None:
        if self.node.lockstep is not None:
            self.node.lockstep.put_scan(conv.stamp_ns(msg.header.stamp), msg)
        else:
            self.use(msg)

    def use(self, msg: LaserScan) -> None:
        """Take one scan now."""
        node = self.node
        c = node.controller
        if c is None or c.pose is None:
            return
        _, ranges = conv.laser_scan_to_ranges(msg)
        if len(ranges) == 0 or not math.isfinite(msg.angle_increment):
            node._warn("scan", "dropped an empty or malformed scan")
            return
        scan = Scan(ranges=ranges, angle_min=float(msg.angle_min),
                    angle_increment=float(msg.angle_increment), range_min=float(msg.range_min),
                    range_max=float(msg.range_max))
        # Safety's obstacles from the pose at the scan's stamp (the newest pose rotates a scan
        # taken while turning by degrees), kept near the robot across scans (ScanMemory).
        stamp = conv.from_time_msg(msg.header.stamp)
        pose = node.poses.at(stamp) or tuple(c.pose)
        c.set_scan(scan, conv.scan_to_points(msg, pose), pose)
        if node.exchange is not None:
            self.pairing.add(stamp, scan)
            self.map_waiting()

    def map_waiting(self) -> None:
        """Exploring: add the scans whose pose is known to the belief."""
        for stamp, scan, pose in self.pairing.ready():
            if pose is None:
                self.node._warn("scanpose", f"dropped a scan at t={stamp:.2f} s: no pose near it")
            else:
                self.node.controller.integrate_scan(scan, pose, self.node._now())
