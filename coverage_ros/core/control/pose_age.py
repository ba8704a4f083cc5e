"""A late pose carried forward to the time of a command, and the log of how late poses were.

A busy process reads its poses late: the tracker and the safety filter steer and check from the
pose carried forward to ``now`` under the last command (a unicycle arc), by at most
:data:`MAX_POSE_AGE`; the ages seen are kept for the log at the end.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from coverage_ros.core.control.safety import unicycle

#: [s] a pose is carried forward under the last command by at most this much of its age.
MAX_POSE_AGE = 0.5
#: Pose ages kept for :meth:`PoseAges.describe`.
POSE_AGES_KEPT = 4096


class PoseAges:
    """The ages [s] of the poses commands were computed from (the last
    :data:`POSE_AGES_KEPT`)."""

    def __init__(self) -> None:
        self.ages: deque[float] = deque(maxlen=POSE_AGES_KEPT)

    def carried(self, pose: np.ndarray, stamp: float | None, v: float, w: float,
                now: float) -> np.ndarray:
        """``pose (x, y, yaw)``, true at ``stamp`` [s] (None: at every ``now``), carried forward
        to ``now`` under ``(v [m/s], w [rad/s])`` by at most :data:`MAX_POSE_AGE`; the age is
        kept."""
        if stamp is None:
            return pose
        age = now - stamp
        self.ages.append(age)
        age = min(max(age, 0.0), MAX_POSE_AGE)
        if age == 0.0:
            return pose
        carried: np.ndarray = unicycle(pose, v, w, np.array([age]))[0]
        return carried

    def describe(self) -> str:
        """One line on how old the poses were when commands were computed ('' if unknown)."""
        if not self.ages:
            return ""
        a = 1e3 * np.asarray(self.ages)
        return (f"pose age at the last {len(a)} commands: median {np.median(a):.0f} ms, 95 % "
                f"{np.percentile(a, 95):.0f} ms, max {a.max():.0f} ms (carried forward up to "
                f"{1e3 * MAX_POSE_AGE:.0f} ms under the last command)")
