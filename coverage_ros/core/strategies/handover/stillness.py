"""Whether a robot stands still, from its positions at its last updates: it moved less than the
convergence tolerance at each of its last :data:`STILL_UPDATES` updates (a step it does not
take: monotone rule, blocked), or those positions stay within a given distance of their mean
(a live robot dithering between goals that flip as its neighbours shift by centimetres: a cell
spanning two rooms has two far apart centroids nearly as good, and the robot turns towards one,
then the other, going nowhere). A robot driving straight at d per update is within 2 d of the
mean: the second rule counts it still only below half the distance per update (with the live
convergence tolerance of 5 cm and an escape_settle of 10 cm, no drive the first rule does not).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: [updates] standing still this long counts as settled: a robot turning towards a new goal
#: stands still for an update or two (half a turn at 2.84 rad/s takes 1.1 s, at 2 Hz).
STILL_UPDATES = 4


@dataclass
class Stillness:
    """One robot's positions at its latest updates."""

    #: [updates] in a row that moved less than the convergence tolerance
    still_for: int = 0
    moved: float = math.inf  # [m] at the latest update (inf: the first)
    #: (<= STILL_UPDATES + 1, 2) [m] the latest positions, the oldest first
    recent: np.ndarray = field(default_factory=lambda: np.empty((0, 2)), repr=False)

    def note(self, position: np.ndarray, tolerance: float, restart: bool = False) -> None:
        """The robot stands at ``position`` [m] at this update; ``tolerance`` [m] is the
        convergence tolerance; ``restart``: its cell changed at once (a neighbour arrived),
        so how it stood so far says nothing."""
        p = np.asarray(position, dtype=np.float64)[:2]
        self.moved = float(np.hypot(*(p - self.recent[-1]))) if len(self.recent) else math.inf
        self.still_for = self.still_for + 1 if self.moved < tolerance else 0
        self.recent = np.vstack([self.recent, p[None, :]])[-(STILL_UPDATES + 1):]
        if restart:
            self.still_for, self.recent = 0, self.recent[-1:]

    def stands(self) -> bool:
        """Moved less than the tolerance at each of the last STILL_UPDATES updates."""
        return self.still_for >= STILL_UPDATES

    def dithers(self, within: float) -> bool:
        """The last STILL_UPDATES + 1 positions all lie within ``within`` [m] of their mean."""
        if len(self.recent) <= STILL_UPDATES:
            return False
        off = self.recent - self.recent.mean(axis=0)
        return bool(np.hypot(off[:, 0], off[:, 1]).max() < within)


@dataclass
class TeamStillness:
    """Whether a robot and every robot it hears have stood within a distance over a window of
    its updates: each robot's own test above takes a robot creeping less than half its settle
    step per update for still, and a team re-spreading after a move creeps so for tens of
    seconds (its H still falling by several % in 10 s) - prices of moves made meanwhile are of
    a passing state."""

    window: int  # [updates] 0: no window (always still)
    #: the configuration keys (:func:`.pricing.config_key`) of the latest updates, oldest first
    recent: list[np.ndarray] = field(default_factory=list, repr=False)

    def note(self, key: np.ndarray) -> None:
        """The robot and those it hears stand at ``key`` (rows: id, x, y) at this update."""
        if self.window > 0:
            self.recent = [*self.recent, key][-(self.window + 1):]

    def restart(self) -> None:
        """The robot moved away from where it stood (a relocation): nothing counts so far."""
        self.recent = []

    def still(self, within: float) -> bool:
        """Every robot heard at the start of the last ``window`` updates (``window + 1`` keys)
        and again since - missed between, at the edge of its range, or at the latest update -
        within ``within`` [m] of its mean position over the updates it was heard in
        (dithering stays so, driving at d per update only below 2 within / window); not still
        while a robot of the latest update was not heard at the start (not known to stand)."""
        if self.window <= 0:
            return True
        if len(self.recent) <= self.window:
            return False
        first, last = self.recent[0], self.recent[-1]
        if not np.isin(last[:, 0], first[:, 0]).all():
            return False
        rows = np.vstack(self.recent)
        for rid in first[:, 0]:
            xy = rows[rows[:, 0] == rid, 1:]
            off = xy - xy.mean(axis=0)
            if not np.hypot(off[:, 0], off[:, 1]).max() < within:
                return False
        return True
