"""One run of TangentBug along an obstacle boundary (:mod:`.bug`), kept the way Breitenmoser et
al. (2010, section III-A) find a goal unreachable: where the robot first touched the boundary
(the anchor), its positions since, the distance travelled and the position closest to the goal.

Back within ``loop_tolerance`` of the anchor after leaving it by twice that, having enclosed at
least :data:`MIN_LOOP_DISCS` discs of that radius, the run has closed a loop round the obstacle.
Points ``(2,) float64`` [m], map frame.
"""

from __future__ import annotations

import math

import numpy as np

from coverage_ros.core.geometry import polygon_area

#: A loop must enclose at least this many loop_tolerance discs (not a walk in and out of a
#: dead end).
MIN_LOOP_DISCS = 1.0


class BoundaryRun:
    """A run along one boundary with the obstacle on ``side`` (+1: left)."""

    def __init__(self, side: int) -> None:
        self.side = side
        self.anchor: np.ndarray | None = None  # first position on the boundary
        self.trace: list[np.ndarray] = []
        self.travelled = 0.0  # [m] since the anchor
        self.best_d = math.inf  # [m] least distance to the goal recorded
        self.best_s = 0.0  # [m] travelled when it was recorded
        self.best: np.ndarray | None = None  # where it was recorded
        self._left_anchor = False
        self._last: np.ndarray | None = None

    def touch(self, x: np.ndarray) -> None:
        """The robot has reached the boundary at ``x``: the anchor."""
        self.anchor = x.copy()
        self._last = x.copy()

    def move_to(self, x: np.ndarray) -> None:
        """The robot is at ``x``: add the way from its last position to the distance."""
        if self._last is not None:
            self.travelled += float(np.hypot(*(x - self._last)))
        self._last = x.copy()

    def record(self, x: np.ndarray, goal: np.ndarray, loop_tolerance: float) -> np.ndarray | None:
        """Add the position ``x`` on the boundary (after :meth:`touch`); the loop's positions
        ``(K, 2)`` when ``x`` closes one (module docstring), else None."""
        assert self._last is not None and self.anchor is not None
        self.move_to(x)
        self.trace.append(x.copy())
        d = float(np.hypot(*(goal - x)))
        if d < self.best_d:
            self.best_d, self.best_s, self.best = d, self.travelled, x.copy()
        gap = float(np.hypot(*(x - self.anchor)))
        if gap > 2.0 * loop_tolerance:
            self._left_anchor = True
        elif self._left_anchor and gap <= loop_tolerance:
            trace = np.array(self.trace)
            if abs(polygon_area(trace)) >= MIN_LOOP_DISCS * math.pi * loop_tolerance ** 2:
                return trace
        return None
