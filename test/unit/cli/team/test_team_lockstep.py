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

    def working_on(self, now: float) -> list[int]:
        return []

    last_working = -float("inf")


def test_a_world_that_stops_ticking_ends_the_run_after_the_stall_timeout(monkeypatch):
    import rclpy

    monkeypatch.setattr(rclpy, "spin_once", lambda node, timeout_sec=None: None)
    monkeypatch.setattr(lockstep, "STALL_TIMEOUT", 0.3)
    observer = StallingObserver()
    with pytest.raises(RuntimeError, match=r"made no tick for 0 s of wall time after sim "
                                           r"time 0.00 s, and no robot has reported working on "
                                           r"it for 0.3 s"):
        lockstep.run_lockstep(StallingMonitor(), observer, startup_timeout=0.2,
                              progress_period=1.0)
    assert observer.answered == [0, 1]


class WorkingObserver(StallingObserver):
    """Tick 1, then robot 2 reports working on it for ever (a long coverage update)."""

    def next_tick(self) -> Tick | None:
        assert time.monotonic() - self.t0 < 5.0, "the launcher waits for ever"
        return self.ticks.pop(0) if self.ticks else None

    def working_on(self, now: float) -> list[int]:
        return [2]

    @property
    def last_working(self) -> float:
        return time.monotonic()


def test_a_tick_held_by_a_working_robot_is_waited_for_past_the_stall_timeout_and_named(
        monkeypatch):
    """A robot still working is not a stuck world: the launcher says every HELD_NOTICE whom the
    tick waits for, and gives up only after HELD_TIMEOUT, naming the robot."""
    import rclpy

    monkeypatch.setattr(rclpy, "spin_once", lambda node, timeout_sec=None: time.sleep(0.01))
    monkeypatch.setattr(lockstep, "STALL_TIMEOUT", 0.1)
    monkeypatch.setattr(lockstep, "HELD_NOTICE", 0.2)
    monkeypatch.setattr(lockstep, "HELD_TIMEOUT", 0.9)
    monitor = StallingMonitor()
    t0 = time.monotonic()
    with pytest.raises(RuntimeError, match=r"made no tick for 0.9 s of wall time after sim time "
                                           r"0.00 s while robots \[2\] reported working"):
        lockstep.run_lockstep(monitor, WorkingObserver(), startup_timeout=0.2,
                              progress_period=1.0)
    assert time.monotonic() - t0 >= 0.9
    held = [line for line in monitor.said if "reported working on it" in line]
    assert 3 <= len(held) <= 5 and all("robots [2]" in line for line in held)


class FinishingObserver(StallingObserver):
    """Robot 2 reports working on tick 1 until 0.5 s after the start, then is done: the world
    steps to the next tick (which, here, never comes)."""

    def working_on(self, now: float) -> list[int]:
        return [2] if now - self.t0 < 0.5 else []

    @property
    def last_working(self) -> float:
        return min(time.monotonic(), self.t0 + 0.5)


def test_the_stall_timeout_counts_from_the_last_robot_working_not_from_the_tick(monkeypatch):
    """The last robot done with a tick held past the stall timeout: the world needs a moment
    to step, which must not look like a stuck world (a warehouse team was given up so, after
    its robots had worked on one tick for five minutes)."""
    import rclpy

    monkeypatch.setattr(rclpy, "spin_once", lambda node, timeout_sec=None: time.sleep(0.01))
    monkeypatch.setattr(lockstep, "STALL_TIMEOUT", 0.3)
    observer = FinishingObserver()
    with pytest.raises(RuntimeError, match=r"no robot has reported working on it for 0.3 s"):
        lockstep.run_lockstep(StallingMonitor(), observer, startup_timeout=0.2,
                              progress_period=1.0)
    assert time.monotonic() - observer.t0 >= 0.8


class Node:
    """Stands for the monitor node: keeps the subscriptions' callbacks by topic."""

    def __init__(self) -> None:
        self.callbacks: dict[str, list] = {}

    def create_publisher(self, *args, **kwargs):
        return None

    def create_subscription(self, msg_type, topic, callback, qos, **kwargs):
        self.callbacks.setdefault(topic, []).append(callback)


def test_the_observer_knows_which_robots_work_on_the_tick_it_answered():
    from coverage_ros.core.lockstep.barrier import DONE, LEAVE, WORKING
    from coverage_ros.nodes import conversions as conv

    node = Node()
    observer = lockstep.LockstepObserver(node, [0, 1, 2])
    report = node.callbacks["/world/tick_report"][0]
    observer.handled = 7
    report(conv.report_msg(WORKING, 7, 0))
    report(conv.report_msg(WORKING, 7, 1))
    report(conv.report_msg(WORKING, 6, 2))  # an older tick's, late
    report(conv.report_msg(WORKING, 7, observer="someone"))
    now = time.monotonic()
    assert observer.working_on(now) == [0, 1]
    assert now - 1.0 < observer.last_working <= now
    report(conv.report_msg(DONE, 7, 1))
    report(conv.report_msg(LEAVE, 7, 2))
    assert observer.working_on(now) == [0]
    assert observer.working_on(now + lockstep.WORKING_FRESH + 1.0) == []  # gone quiet
