"""Goals for an external navigator (``robot_node`` with ``drive: false``).

A robot that keeps its own navigation stack (Nav2's bt_navigator, move_base) gets the coverage
goal instead of velocity commands. A navigator replans on every goal it receives, so a goal is
sent again only when it moved by more than ``resend_distance`` - a Lloyd goal creeps by
millimetres every update near convergence, and re-sending those would make the navigator
restart its behaviour tree every half second. The goal's heading points along the way from
the robot to the goal, so the navigator does not turn the robot on the spot when it arrives.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class GoalRelay:
    """Decides which goals go to the navigator (see module docstring)."""

    resend_distance: float = 0.25  # [m]
    sent: np.ndarray | None = field(default=None, init=False)  # (3,) the last goal sent
    count: int = field(default=0, init=False)  # goals sent so far

    def offer(self, goal: np.ndarray, pose: np.ndarray) -> np.ndarray | None:
        """``(x, y, yaw)`` to send for the strategy's ``goal (2,)`` seen from ``pose (3,)``, or
        None when the last goal sent is still close enough."""
        goal = np.asarray(goal, dtype=np.float64)[:2]
        if not np.all(np.isfinite(goal)):
            return None
        if self.sent is not None and \
                float(np.hypot(*(goal - self.sent[:2]))) <= self.resend_distance:
            return None
        d = goal - np.asarray(pose[:2], dtype=np.float64)
        yaw = math.atan2(d[1], d[0]) if float(np.hypot(*d)) > 1e-6 else float(pose[2])
        self.sent = np.array([goal[0], goal[1], yaw])
        self.count += 1
        return self.sent.copy()

    def reset(self) -> None:
        """Forget the last goal (the navigator lost it, e.g. after a pause)."""
        self.sent = None
