"""Path tracking of a differential-drive robot: pure pursuit within its speed and acceleration
limits.

:class:`PathTracker` steers toward a look-ahead point on the path (:func:`carrot`), turns in
place when it lies far off the heading, slows down near the goal; velocities are limited to
``v_max``/``w_max`` and their changes to ``a_max``/``alpha_max``.

Poses are ``(x, y, yaw)`` in the map frame [m, rad]; paths are ``(M, 2)`` map-frame points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.geometry import wrap_angle
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.errors import ConfigError


@dataclass(frozen=True)
class TrackerConfig:
    v_max: float = RobotSpec().v_max  # [m/s]
    w_max: float = RobotSpec().w_max  # [rad/s]
    a_max: float = RobotSpec().a_max  # [m/s^2]
    alpha_max: float = RobotSpec().alpha_max  # [rad/s^2]
    lookahead: float = 0.25  # [m] carrot distance along the path
    goal_tolerance: float = 0.05  # [m] closer than this = arrived
    heading_gain: float = 2.5  # [1/s] w = gain * heading error
    turn_in_place: float = 1.0  # [rad] heading error above which the robot only turns
    slow_radius: float = 0.4  # [m] speed ramps down inside this distance of the goal

    def __post_init__(self) -> None:
        for name in ("v_max", "w_max", "a_max", "alpha_max", "lookahead", "goal_tolerance",
                     "heading_gain", "turn_in_place", "slow_radius"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError.at(name, "must be a finite number > 0", v)

    @classmethod
    def for_robot(cls, robot: RobotSpec, **kw: float) -> TrackerConfig:
        return cls(v_max=robot.v_max, w_max=robot.w_max, a_max=robot.a_max,
                   alpha_max=robot.alpha_max, **kw)


class PathTracker:
    """Pure pursuit with speed and acceleration limits (see module docstring)."""

    def __init__(self, config: TrackerConfig) -> None:
        self.config = config
        self.v = 0.0
        self.w = 0.0

    def reset(self) -> None:
        self.v = self.w = 0.0

    def command(self, pose: np.ndarray, path: np.ndarray | None, dt: float,
                ) -> tuple[float, float, bool]:
        """``(v, w, arrived)`` for this control step of ``dt`` seconds."""
        c = self.config
        if path is None or len(path) == 0:
            return self._limit(0.0, 0.0, dt) + (True,)
        p = np.asarray(pose[:2], dtype=np.float64)
        goal = path[-1]
        to_goal = float(np.hypot(*(goal - p)))
        if to_goal < c.goal_tolerance:
            return self._limit(0.0, 0.0, dt) + (True,)
        target = carrot(path, p, c.lookahead)
        error = float(wrap_angle(math.atan2(target[1] - p[1], target[0] - p[0]) - pose[2]))
        w = float(np.clip(c.heading_gain * error, -c.w_max, c.w_max))
        if abs(error) > c.turn_in_place:
            v = 0.0
        else:
            v = c.v_max * math.cos(error) * min(1.0, to_goal / c.slow_radius)
            v = max(v, 0.0)
        return self._limit(v, w, dt) + (False,)

    def _limit(self, v: float, w: float, dt: float) -> tuple[float, float]:
        c = self.config
        self.v = float(np.clip(v, self.v - c.a_max * dt, self.v + c.a_max * dt))
        self.w = float(np.clip(w, self.w - c.alpha_max * dt, self.w + c.alpha_max * dt))
        self.v = float(np.clip(self.v, -c.v_max, c.v_max))
        self.w = float(np.clip(self.w, -c.w_max, c.w_max))
        return self.v, self.w

    def override(self, v: float, w: float) -> None:
        """Tell the tracker what was really commanded (after the safety filter)."""
        self.v, self.w = float(v), float(w)


def carrot(path: np.ndarray, p: np.ndarray, lookahead: float) -> np.ndarray:
    """The point ``lookahead`` metres along the path beyond the point of the path nearest to
    ``p`` (the goal if the path ends sooner)."""
    if len(path) == 1:
        only: np.ndarray = path[0]
        return only
    a, b = path[:-1], path[1:]
    ab = b - a
    L2 = np.maximum((ab * ab).sum(axis=1), 1e-12)
    t = np.clip(((p - a) * ab).sum(axis=1) / L2, 0.0, 1.0)
    d = np.hypot(*(a + t[:, None] * ab - p).T)
    k = int(np.argmin(d))
    seg_len = np.sqrt(L2)
    pos = t[k] * seg_len[k]
    # The carrot stays on the current segment: looking past a corner would cut it.
    point: np.ndarray
    if seg_len[k] - pos >= lookahead:
        point = a[k] + ab[k] * ((pos + lookahead) / seg_len[k])
    elif seg_len[k] - pos > 0.5 * lookahead or k == len(ab) - 1:
        point = b[k]
    else:
        nxt = k + 1  # nearly at the corner: start along the next segment
        point = a[nxt] + ab[nxt] * min(1.0, (lookahead - (seg_len[k] - pos)) / seg_len[nxt])
    return point
