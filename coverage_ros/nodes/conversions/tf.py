"""Message conversions: transforms (``/tf``, ``/tf_static``; conventions: :mod:`..conversions`).

``tf2_msgs`` is not on PyPI; ``scripts/bootstrap.sh`` builds ``tf2_msgs/msg/TFMessage`` into the
venv. Where it is missing, :data:`TFMessage` is None and the nodes say that /tf is off.
"""

from __future__ import annotations

from builtin_interfaces.msg import Time
from geometry_msgs.msg import TransformStamped

from coverage_ros.nodes.conversions.basics import (
    from_time_msg,
    quaternion_problem,
    quaternion_to_yaw,
    stamp_problem,
    yaw_to_quaternion,
)

try:
    from tf2_msgs.msg import TFMessage
except ImportError:  # not built (see module docstring)
    TFMessage = None


def transform_msg(stamp: Time, parent: str, child: str,
                  pose: tuple[float, float, float]) -> TransformStamped:
    """``parent <- child`` as a planar ``(x, y, yaw)``."""
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.translation.x = float(pose[0])
    t.transform.translation.y = float(pose[1])
    t.transform.rotation = yaw_to_quaternion(pose[2])
    return t


def tf_message(transforms: list[TransformStamped]):
    msg = TFMessage()
    msg.transforms = transforms
    return msg


def transforms_of(msg) -> tuple[list[tuple[str, str, tuple[float, float, float], float]],
                                 list[str]]:
    """``(parent, child, (x, y, yaw), stamp [s])`` of each well-formed transform in a
    ``TFMessage``, and why each of the others is not (an impossible stamp, a rotation that is
    not a unit quaternion)."""
    out, dropped = [], []
    for t in msg.transforms:
        problem = stamp_problem(t.header.stamp) or quaternion_problem(t.transform.rotation)
        if problem is not None:
            dropped.append(f"{t.header.frame_id!r} <- {t.child_frame_id!r}: {problem}")
            continue
        tr = t.transform.translation
        out.append((t.header.frame_id, t.child_frame_id,
                    (tr.x, tr.y, quaternion_to_yaw(t.transform.rotation)),
                    from_time_msg(t.header.stamp)))
    return out, dropped
