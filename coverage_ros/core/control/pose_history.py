"""Where a robot was at a given time: its recent poses, interpolated.

A lidar scan is stamped with the time it was taken, and the pose that came last may be a tenth
of a second older or newer. Drawn from the wrong pose, a scan of a robot turning at 2.8 rad/s
is rotated by a quarter of a radian - a wall 3 m away moves by 0.8 m - so scans are placed with
the pose at their own stamp: an exploring robot's belief, and the viewer's scan layer.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

#: [s] pose history kept per robot (scans arrive at 5 Hz, poses at 10-20 Hz).
POSE_HISTORY = 2.0
#: [s] how far a scan stamp may lie outside the pose history and still use its nearest pose.
POSE_TOLERANCE = 0.5
#: [s] a stamp further back than this before the newest is a restarted simulation.
TIME_JUMP_BACK = 1.0
#: [s] a velocity from poses is the mean over this long (odometry at 10-20 Hz: a few samples).
VELOCITY_WINDOW = 0.3
#: [s] samples closer in time than this give no velocity (their noise would dominate).
MIN_VELOCITY_SPAN = 0.05


class PoseHistory:
    """A robot's recent ``(t, x, y, yaw)`` samples (stamps in seconds, increasing)."""

    def __init__(self, span: float = POSE_HISTORY) -> None:
        self.span = span
        self._samples: deque[tuple[float, float, float, float]] = deque()

    def add(self, t: float, pose: tuple[float, float, float]) -> None:
        if self._samples and t < self._samples[-1][0]:
            if t < self._samples[-1][0] - TIME_JUMP_BACK:
                self._samples.clear()  # time went back: a new run
            else:
                return  # out of order: keep the history sorted
        self._samples.append((t, *pose))
        while self._samples[-1][0] - self._samples[0][0] > self.span:
            self._samples.popleft()

    @property
    def latest(self) -> tuple[float, float, float] | None:
        return self._samples[-1][1:] if self._samples else None

    @property
    def latest_time(self) -> float | None:
        return self._samples[-1][0] if self._samples else None

    def at(self, t: float) -> tuple[float, float, float] | None:
        """The pose at ``t``: interpolated between samples (yaw along the short way), the
        nearest sample within POSE_TOLERANCE outside them, else None."""
        if not self._samples:
            return None
        first, last = self._samples[0], self._samples[-1]
        if t <= first[0]:
            return first[1:] if first[0] - t <= POSE_TOLERANCE else None
        if t >= last[0]:
            return last[1:] if t - last[0] <= POSE_TOLERANCE else None
        stamps = np.fromiter((s[0] for s in self._samples), dtype=np.float64)
        k = int(np.searchsorted(stamps, t))
        (t0, x0, y0, a0), (t1, x1, y1, a1) = self._samples[k - 1], self._samples[k]
        f = (t - t0) / (t1 - t0) if t1 > t0 else 1.0
        da = math.remainder(a1 - a0, 2.0 * math.pi)
        return (x0 + f * (x1 - x0), y0 + f * (y1 - y0),
                math.remainder(a0 + f * da, 2.0 * math.pi))

    def velocity(self, window: float = VELOCITY_WINDOW) -> dict[str, float]:
        """``vx``, ``vy`` [m/s] (the poses' frame): the mean velocity over the last ``window``
        seconds of samples (from the newest one back to the last one at least ``window`` older,
        or the oldest kept); empty when fewer than two samples span MIN_VELOCITY_SPAN. For a
        robot whose commands this stack does not send (``drive: false``: its own navigator
        drives it), what its neighbours' safety filters get instead of the command's velocity."""
        if len(self._samples) < 2:
            return {}
        t1, x1, y1, _ = self._samples[-1]
        older = [s for s in self._samples if s[0] <= t1 - window]
        t0, x0, y0, _ = older[-1] if older else self._samples[0]
        if t1 - t0 < MIN_VELOCITY_SPAN:
            return {}
        return {"vx": (x1 - x0) / (t1 - t0), "vy": (y1 - y0) / (t1 - t0)}


#: Scans that wait for the pose after their stamp (a second of a 5 Hz lidar).
PENDING_SCANS = 5


class ScanPairing:
    """Scans waiting for their pose: a scan is placed from the pose at its own stamp, so one
    newer than the newest pose waits for the next pose; one older than the history is dropped
    (a map drawn from a wrong pose is worse than a scan less). At most ``keep`` wait."""

    def __init__(self, poses: PoseHistory, keep: int = PENDING_SCANS) -> None:
        self.poses = poses
        self._waiting: deque[tuple[float, object]] = deque(maxlen=keep)

    def add(self, stamp: float, scan: object) -> None:
        self._waiting.append((stamp, scan))

    def ready(self) -> list[tuple[float, object, tuple[float, float, float] | None]]:
        """``(stamp, scan, pose at the stamp or None)`` of every scan whose pose is known now,
        oldest first (None: no pose near its stamp - drop it)."""
        out = []
        newest = self.poses.latest_time
        while self._waiting and newest is not None and self._waiting[0][0] <= newest:
            stamp, scan = self._waiting.popleft()
            out.append((stamp, scan, self.poses.at(stamp)))
        return out
