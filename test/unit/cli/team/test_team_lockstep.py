"""The launcher's lock-step loop (cli/team/lockstep.py) without DDS: a fake monitor and
observer stand for the node and the world's ticks."""

from __future__ import annotations

import time

import pytest

from coverage_ros.cli.team import lockstep
from coverage_ros.cli.team.summary import RunLog
from coverage_ros.core.lockstep import Tick


class Monitor:
    def __init__(self) -> None:
        self.log = RunLog()
        self.proc_stats = None
        self.said: list[str] = []

    def say(self, text: str) -> None:
        self.said.append(text)

    def check_children(self, starting: bool) -> None:
        pass

    def alive(self) -> list[int]:
        return [0, 1, 2]


class Observer:
    """The world repeats tick 0 listing robots 1 and 2 only: robot 0 never joined. A launcher
    still waiting 5 s later fails the test instead of hanging it."""

    def __init__(self) -> None:
        self.t0 = time.monotonic()

    def beat(self) -> None:
        pass

    def next_tick(self) -> Tick:
        assert time.monotonic() - self.t0 < 5.0, "the launcher waits for ever"
        return Tick(0, 0, -1, 0.1, robots=frozenset({1, 2}))


def test_a_robot_that_never_joins_ends_the_start_up_after_the_timeout(monkeypatch):
    """The world holds tick 0 for the launcher's answer, which waits for every robot: the
    launcher gives up after its start-up timeout and names the robot, instead of both waiting
    for ever."""
    import rclpy

    monkeypatch.setattr(rclpy, "spin_once", lambda node, timeout_sec=None: None)
    with pytest.raises(RuntimeError, match=r"did not list robots \[0\] within 0.2 s"):
        lockstep.run_lockstep(Monitor(), Observer(), startup_timeout=0.2, progress_period=1.0)


class StallingMonitor(Monitor):
    end = 100.0  # [s] sim time
    exploration = None
    config = None

    def team_ready(self, t0: float) -> None:
        self.log.ready_at = 0.0

    def apply_faults(self, t: float, slack: float = 0.0) -> None:
        pass

    def cost(self) -> float:
        return 1.0

    def progress(self, final: bool = False) -> None:
        pass


class StallingObserver:
    """Every robot is in from tick 0; tick 1 comes, then nothing (a stuck world)."""

    def __init__(self) -> None:
        self.t0 = time.monotonic()
        self.ticks = [Tick(0, 0, -1, 0.0, robots=frozenset({0, 1, 2})),
                      Tick(1, 1_000_000, -1, 0.001, robots=frozenset({0, 1, 2}))]
        self.answered: list[int] = []

    def beat(self) -> None:
        pass

    def next_tick(self) -> Tick | None:
        assert time.monotonic() - self.t0 < 5.0, "the launcher waits for ever"
        return self.ticks.pop(0) if self.ticks else None

    def answer(self, tick: Tick) -> None:
        self.answered.append(tick.index)


def test_a_world_that_stops_ticking_ends_the_run_after_the_stall_timeout(monkeypatch):
    import rclpy

    monkeypatch.setattr(rclpy, "spin_once", lambda node, timeout_sec=None: None)
    monkeypatch.setattr(lockstep, "STALL_TIMEOUT", 0.3)
    observer = StallingObserver()
    with pytest.raises(RuntimeError, match=r"made no tick for 0.3 s of wall time after sim "
                                           r"time 0.00 s"):
        lockstep.run_lockstep(StallingMonitor(), observer, startup_timeout=0.2,
                              progress_period=1.0)
    assert observer.answered == [0, 1]
