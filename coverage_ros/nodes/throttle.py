"""Warnings that a stream of bad messages cannot turn into a stream of log lines."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable

#: [s] wall time between two warnings of the same kind.
WARN_PERIOD = 5.0


class WarnThrottle:
    """Warnings at most once per ``period`` (wall time) per key; safe from any thread.

    ``throttle.warn("scan", "dropped an empty scan")`` logs through ``log`` (a node logger's
    ``warning``) unless the same key was logged less than ``period`` seconds ago."""

    def __init__(self, log: Callable[[str], object], period: float = WARN_PERIOD) -> None:
        self._log = log
        self.period = period
        self._last: dict[str, float] = {}
        self._lock = threading.Lock()

    def warn(self, key: str, text: str) -> bool:
        """Log ``text`` if ``key`` is due; whether it was logged."""
        now = time.monotonic()
        with self._lock:
            if now - self._last.get(key, -math.inf) < self.period:
                return False
            self._last[key] = now
        self._log(text)
        return True
