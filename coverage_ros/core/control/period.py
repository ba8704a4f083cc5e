"""The control period a strategy just had: the time since its last update, for strategies
that scale a step by it (``bvc``, the baselines of Wang et al.'s Table I).

A period longer than :data:`MAX_PERIOD_FACTOR` nominal periods (a pause, a restart, a robot
that was starved of CPU) is not used to scale the step; the nominal period is, as is the first
one.
"""

from __future__ import annotations

#: An observed period longer than this many nominal periods is replaced by the nominal one.
MAX_PERIOD_FACTOR = 5.0


class ControlPeriod:
    """Measures the period between successive calls of :meth:`elapsed` (sim time)."""

    def __init__(self, nominal: float) -> None:
        self.nominal = float(nominal)  # [s]
        self._last: float | None = None

    def elapsed(self, now: float) -> float:
        """[s] the period since the last call at ``now`` [s] (the nominal one first, after a
        pause and when time ran backwards)."""
        last, self._last = self._last, float(now)
        if last is None:
            return self.nominal
        dt = float(now) - last
        return dt if 0.0 < dt <= MAX_PERIOD_FACTOR * self.nominal else self.nominal
