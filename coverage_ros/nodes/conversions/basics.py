"""Message conversions: time, angles and frames (conventions: :mod:`..conversions`)."""


from __future__ import annotations

import math
from dataclasses import dataclass

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion
from rosgraph_msgs.msg import Clock

MAP_FRAME = "map"
#: A quaternion whose squared norm is farther than this from 1 is not an orientation (tf2 drops
#: such transforms with the same tolerance).
QUATERNION_TOLERANCE = 0.01


# ---------------------------------------------------------------------------- time and angles
def to_time_msg(seconds: float) -> Time:
    """Sim time [s] -> ``builtin_interfaces/Time``."""
    ns = round(seconds * 1e9)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def from_time_msg(stamp: Time) -> float:
    """``builtin_interfaces/Time`` -> seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def stamp_problem(stamp: Time) -> str | None:
    """Why ``stamp`` is impossible (nanosec not below 1e9), or None."""
    if not 0 <= stamp.nanosec < 1_000_000_000:
        return f"stamp nanosec {stamp.nanosec} is not below 1e9"
    return None


def quaternion_problem(q: Quaternion) -> str | None:
    """Why ``q`` is not an orientation (non-finite, or not of unit length), or None."""
    norm2 = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w
    if not (math.isfinite(norm2) and abs(norm2 - 1.0) <= QUATERNION_TOLERANCE):
        return f"orientation ({q.x:g}, {q.y:g}, {q.z:g}, {q.w:g}) is not a unit quaternion"
    return None


def clock_msg(seconds: float) -> Clock:
    return Clock(clock=to_time_msg(seconds))


def yaw_to_quaternion(yaw: float) -> Quaternion:
    """A rotation of ``yaw`` [rad] about z."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(0.5 * yaw), w=math.cos(0.5 * yaw))


def quaternion_to_yaw(q: Quaternion) -> float:
    """Yaw [rad] of a quaternion (its rotation about z, for planar poses)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


# ---------------------------------------------------------------------------- frames
@dataclass(frozen=True)
class RobotFrames:
    """Names of one robot's namespace and frames (see module docstring)."""

    namespace: str  # "/robot_3"
    odom: str  # "robot_3/odom"
    base_link: str  # "robot_3/base_link"
    base_scan: str  # "robot_3/base_scan"

    @classmethod
    def of(cls, prefix: str, robot_id: int) -> RobotFrames:
        name = f"{prefix}{robot_id}"
        return cls(f"/{name}", f"{name}/odom", f"{name}/base_link", f"{name}/base_scan")

    def topic(self, name: str) -> str:
        return f"{self.namespace}/{name}"

