"""When a moving robot has finished an iteration of Alg. 2 - the pace of the dropout's end test.

Alg. 2 tests Delta I = I_{t-1} - I_t once per *iteration*: every agent has jumped to its goal.
The paper's epsilon (0.002) is a per-iteration figure. A live robot updates every 0.5 s and
drives at most v_max * 0.5 s in that time, so I sampled per update changes by a fraction of an
iteration's worth - and a robot crossing a doorway can raise I for a moment. Fed per update, the
filtered Delta I falls below epsilon within seconds of the start and the dropout ends before
it has moved anyone. The paper's real-time form (Alg. 3) tests Delta I between whole
iterations too.

So the decentralized switch is fed once per iteration, and an iteration of a robot ends when

* its own move is done: it is within ``arrive`` of the goal it took at its last sample, or has
  had the time to drive there (straight-line distance / v_max, times ``slack``, plus
  ``margin``), and
* every neighbour still in its dropout has done at least as many iterations (each publishes
  its count) - a barrier, so that a robot that arrives early, or had no move to make, samples
  I once the others have moved too. The barrier keeps neighbours within one iteration of each
  other, so a neighbour two or more behind is out of step - it started or restarted late, or
  comes from a part of the team that was out of range (``comm_range``) - and is not waited for
  (it would catch up one iteration per update at best, and the neighbourhood's test would
  stand still until it had). Instead it takes up the count of the neighbours ahead of it at its
  next sample (a Lamport clock: the count is the team's iteration, not the robot's own tally),
  and is in step from then on.

A robot that jumps to its goal at once (the offline runner) has done its move at the next
update, and its neighbours' counts, one update old, equal its own: it samples every update,
exactly as before. A neighbour that left its dropout stops counting and is not waited for; the
own move's time limit keeps a robot that never reaches its goal from holding the team.

Nor is I tested before every neighbour that runs the dropout has published a mass: the live
robots make their first updates a few tenths of a second apart, and a test on the masses of
the first two or three (no mass at or above tau_drop = k / (k - 1) mean M among them) would
end the dropout before the team is split.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from coverage_ros.core.strategies.base import SharedState

#: Shared-state key of the iteration count a robot publishes while its dropout is on.
ITERATION_KEY = "iteration"


class MoveIterations:
    """Counts a robot's iterations of Alg. 2 and says when the next one is done."""

    def __init__(self, speed: float, arrive: float, slack: float = 2.0,
                 margin: float = 1.0) -> None:
        self.speed = max(float(speed), 1e-9)  # [m/s] v_max
        self.arrive = float(arrive)  # [m] within this of the goal, the move is done
        self.slack = float(slack)  # travel-time factor over the straight line at v_max
        self.margin = float(margin)  # [s] added to the travel time (turning, starting)
        self.count = 0  # iterations done (samples of I taken)
        self._goal: np.ndarray | None = None  # goal taken at the last sample [m]
        self._stamp = -math.inf  # [s] time of the last sample
        self._limit = 0.0  # [s] time allowed for the move from the last sample

    def due(self, position: np.ndarray, stamp: float, peers: Iterable[float]) -> bool:
        """Whether the iteration begun at the last sample is over at ``position`` and
        ``stamp`` [s], given the counts ``peers`` published by neighbours still in dropout."""
        if self._goal is not None:
            arrived = float(np.hypot(*(np.asarray(position, float) - self._goal))) <= self.arrive
            elapsed = stamp - self._stamp
            if not (arrived or elapsed >= self._limit or elapsed < 0.0):
                return False
        # (c = count - 1: one behind, still moving; less: out of step, see module docstring)
        return all(c >= self.count or c < self.count - 1 for c in peers)

    def sampled(self, position: np.ndarray, goal: np.ndarray, stamp: float,
                peers: Iterable[float] = ()) -> None:
        """A sample was taken at ``stamp``; the robot now heads from ``position`` to
        ``goal``. ``peers``: the counts that :meth:`due` was given; a robot behind them takes
        up the largest (module docstring)."""
        self.count = max(self.count + 1, int(max(peers, default=0)))
        self._goal = np.asarray(goal, dtype=np.float64).copy()
        self._stamp = float(stamp)
        distance = float(np.hypot(*(self._goal - np.asarray(position, float))))
        self._limit = self.slack * distance / self.speed + self.margin


def peer_counts(states: Iterable[SharedState]) -> list[float]:
    """Iteration counts published by the neighbours (``SharedState``) still in their dropout;
    a neighbour that publishes no count (another strategy, an older node) is not waited for."""
    counts = []
    for st in states:
        extra = st.extra
        if extra.get("dropout", 0.0) == 1.0 and ITERATION_KEY in extra:
            counts.append(float(extra[ITERATION_KEY]))
    return counts


def awaiting_mass(states: Iterable[SharedState]) -> bool:
    """Whether a neighbour that runs the dropout (it publishes ``dropout``, from its first
    state on) has not published a cell mass yet: it has not made its first update."""
    return any("dropout" in st.extra and not (st.mass is not None and math.isfinite(st.mass))
               for st in states)
