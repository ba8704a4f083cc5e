"""Robot faults on schedule (``--kill``, ``--restart``): which robot, when, and carrying them out
on the launcher's processes.

A kill ends a robot's process for good (SIGKILL) and asks the world to take its body away; a
restart kills the process and starts it again at once with the same parameters while its body
stays where it is, as a robot whose software crashed would.
"""

from __future__ import annotations

import contextlib
import math
import signal
import subprocess
from collections.abc import Callable
from dataclasses import dataclass

from coverage_ros.cli.team.processes import ProcessSet
from coverage_ros.errors import ConfigError

KILL = "kill"
RESTART = "restart"


@dataclass(frozen=True, order=True)
class Fault:
    """``action`` of robot ``robot`` at ``time`` [s] of sim time after the team was ready."""

    time: float
    robot: int
    action: str


def parse_faults(kills: tuple[str, ...] | list[str], restarts: tuple[str, ...] | list[str],
                 n: int, duration: float = math.inf) -> list[Fault]:
    """``--kill`` and ``--restart`` ``ID@SECONDS`` items for a team of ``n`` in a run of
    ``duration`` [s], sorted by time."""
    out: list[Fault] = []
    for option, action, specs in (("--kill", KILL, kills), ("--restart", RESTART, restarts)):
        for spec in specs:
            try:
                rid, t = spec.split("@")
                fault = Fault(float(t), int(rid), action)
            except ValueError:
                raise ConfigError.at(option, "must be ID@SECONDS", spec) from None
            if not 0 <= fault.robot < n:
                raise ConfigError.at(option, f"robot id out of range 0..{n - 1}", spec)
            if not (math.isfinite(fault.time) and fault.time >= 0):
                raise ConfigError.at(option, "needs a time >= 0 [s]", spec)
            if fault.time >= duration:
                raise ConfigError.at(option, f"comes after the run's end (--duration "
                                     f"{duration:g} s)", spec)
            out.append(fault)
    kill_list = [f.robot for f in out if f.action == KILL]
    twice = sorted({r for r in kill_list if kill_list.count(r) > 1})
    if twice:
        raise ConfigError.at("--kill", "kills a robot twice", twice, "each robot at most once")
    killed = {f.robot: f.time for f in out if f.action == KILL}
    for f in out:
        if f.action == RESTART and killed.get(f.robot, math.inf) <= f.time:
            raise ConfigError.at("--restart", f"robot {f.robot} is killed (--kill) before that",
                                 f"{f.robot}@{f.time:g}")
    return sorted(out)


class FaultSchedule:
    """The faults still to come, carried out on ``procs``: ``relaunch(robot)`` starts a robot's
    process again, ``remove(robot)`` takes a killed robot's body out of the world, ``say``
    reports each."""

    #: [s] wall time a killed process gets to be gone before its restart.
    RESTART_WAIT = 3.0

    def __init__(self, faults: list[Fault], procs: ProcessSet,
                 relaunch: Callable[[int], object], remove: Callable[[int], None],
                 say: Callable[[str], object]) -> None:
        self.pending = sorted(faults)
        self.procs, self.relaunch, self.remove, self.say = procs, relaunch, remove, say

    def due(self, t: float, slack: float = 0.0) -> list[Fault]:
        """The faults due at ``t`` [s since ready] (``slack``: allowed rounding), taken off."""
        out = []
        while self.pending and t >= self.pending[0].time - slack:
            out.append(self.pending.pop(0))
        return out

    def kill(self, robot: int, t: float) -> None:
        self.say(f"\n  killing robot {robot} at sim time {t:.1f} s")
        self.procs.signal(f"robot_{robot}", signal.SIGKILL)
        self.remove(robot)

    def restart(self, robot: int, t: float) -> None:
        self.say(f"\n  restarting robot {robot} at sim time {t:.1f} s")
        name = f"robot_{robot}"
        self.procs.signal(name, signal.SIGKILL)
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.procs.children[name].popen.wait(timeout=self.RESTART_WAIT)
        self.relaunch(robot)
