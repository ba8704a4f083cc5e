"""Message conversions: odometry, laser scans and velocity commands (conventions:
:mod:`..conversions`)."""


from __future__ import annotations

import array
import math

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

from coverage_ros.core.world import LidarSpec
from coverage_ros.nodes.conversions.basics import quaternion_to_yaw, yaw_to_quaternion


# ---------------------------------------------------------------------------- odometry
def odometry_msg(stamp: Time, frame_id: str, child_frame_id: str,
                 pose: tuple[float, float, float], twist: tuple[float, float, float],
                 variance: tuple[float, float] = (0.0, 0.0),
                 out: Odometry | None = None) -> Odometry:
    """``nav_msgs/Odometry`` of a planar pose ``(x, y, yaw)`` in ``frame_id`` and a body-frame
    twist ``(vx, vy, w)`` in ``child_frame_id``; ``variance`` = ``(var_xy [m^2], var_yaw
    [rad^2])`` goes on the pose covariance diagonal. Pass ``out`` to refill a message instead of
    building one (an ``Odometry()`` costs ~60 us; publishing serializes it right away)."""
    msg = Odometry() if out is None else out
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    msg.pose.pose.position.x = float(pose[0])
    msg.pose.pose.position.y = float(pose[1])
    msg.pose.pose.orientation = yaw_to_quaternion(pose[2])
    if variance[0] or variance[1] or out is not None:
        cov = msg.pose.covariance
        cov[0] = cov[7] = float(variance[0])
        cov[35] = float(variance[1])
    msg.twist.twist.linear.x = float(twist[0])
    msg.twist.twist.linear.y = float(twist[1])
    msg.twist.twist.angular.z = float(twist[2])
    return msg


def odometry_to_pose(msg: Odometry) -> tuple[float, float, float]:
    """``(x, y, yaw)`` of an ``nav_msgs/Odometry`` message, in its header frame."""
    p = msg.pose.pose
    return p.position.x, p.position.y, quaternion_to_yaw(p.orientation)


# ---------------------------------------------------------------------------- laser scans
def laser_scan_msg(ranges: np.ndarray, lidar: LidarSpec, stamp: Time, frame_id: str) -> LaserScan:
    """``sensor_msgs/LaserScan`` from ``(B,)`` ranges [m] (REP 117 values kept)."""
    msg = LaserScan()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.angle_min = float(lidar.angle_min)
    msg.angle_increment = float(lidar.angle_increment)
    msg.angle_max = float(lidar.angle_min + lidar.angle_increment * (lidar.beams - 1))
    msg.time_increment = 0.0  # the simulated scan is instantaneous
    msg.scan_time = float(1.0 / lidar.rate_hz)
    msg.range_min = float(lidar.range_min)
    msg.range_max = float(lidar.range_max)
    msg.ranges = array.array("f", np.asarray(ranges, dtype=np.float32).tobytes())
    return msg


def laser_scan_to_ranges(msg: LaserScan) -> tuple[np.ndarray, np.ndarray]:
    """``(angles, ranges)``, each ``(B,) float64``: beam angles [rad] in the scan frame and
    ranges [m] (inf/-inf kept)."""
    ranges = np.asarray(msg.ranges, dtype=np.float64)
    angles = msg.angle_min + msg.angle_increment * np.arange(len(ranges))
    return angles, ranges


# ---------------------------------------------------------------------------- commands
def twist_to_command(msg: Twist) -> tuple[float, float]:
    """``(v [m/s], w [rad/s])`` of a ``cmd_vel`` twist; ValueError if not finite."""
    v, w = float(msg.linear.x), float(msg.angular.z)
    if not (math.isfinite(v) and math.isfinite(w)):
        raise ValueError(f"cmd_vel must be finite (got linear.x={v!r}, angular.z={w!r})")
    return v, w


def command_to_twist(v: float, w: float) -> Twist:
    msg = Twist()
    msg.linear.x = float(v)
    msg.angular.z = float(w)
    return msg

