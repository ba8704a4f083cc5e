"""Signals as KeyboardInterrupt for the command-line tools that spin rclpy themselves
(``coverage-team``, ``coverage-teleop``), and which exceptions they mean."""

from __future__ import annotations

import signal


class Interrupts:
    """The ``signals`` raised as KeyboardInterrupt from now on, and remembered: one raised
    while rclpy's C++ builds a message in Python comes out as pybind11's conversion error (a
    RuntimeError, "Unable to convert call argument"), which after a signal is the interrupt."""

    def __init__(self, signals: tuple[int, ...] = (signal.SIGINT, signal.SIGTERM)) -> None:
        self.signals = signals
        self.received: list[int] = []
        self.previous = {sig: signal.signal(sig, self._raise) for sig in signals}

    def _raise(self, signum, frame) -> None:
        self.received.append(signum)
        raise KeyboardInterrupt

    def caused(self, exc: BaseException) -> bool:
        """``exc`` ends the run as an interrupt (not as a failure)."""
        return isinstance(exc, KeyboardInterrupt) or bool(self.received)

    def ignore(self) -> None:
        for sig in self.signals:
            signal.signal(sig, signal.SIG_IGN)

    def restore(self) -> None:
        for sig, previous in self.previous.items():
            signal.signal(sig, previous)
