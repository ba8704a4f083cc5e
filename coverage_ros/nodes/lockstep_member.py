"""The lock-step member side of a robot process (``robot_node`` / ``robot_container`` with
``lockstep: true``): one :class:`LockstepDriver` per process answers the world's ticks for the
process's robots.

* ``/world/tick`` (in, one subscription per process): each tick is worked on by the driver's
  own thread, robot after robot in id order (so robots sharing a process - and its search
  cache - compute the same whatever the thread timing): it waits until the robot's inputs of
  the tick are in (:meth:`LockstepRobot.missing`), runs the robot's tick
  (:meth:`LockstepRobot.step`: inputs, coverage update when due, command, messages) and
  reports DONE with the command;
* ``/world/tick_report`` (out): JOIN for each robot that is ready (its map or belief is built
  and it has heard its pose and a tick) until a tick lists it; WORKING every
  :data:`HEARTBEAT` seconds of wall time for a robot still working on the current tick (a long
  coverage update is waited for, a dead process is not); DONE for a tick seen again that was
  already answered (the answer was lost); LEAVE at shutdown.

A robot whose inputs do not all arrive within :data:`INPUT_TIMEOUT` of wall time (a neighbour
died after answering) goes on without them, with one warning.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Protocol

from coverage_msgs.msg import LockstepReport, LockstepTick
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from coverage_ros.core.lockstep import Tick
from coverage_ros.core.lockstep.barrier import DONE, JOIN, LEAVE, WORKING
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.qos import REPORT_QOS, TICK_QOS

#: [s] wall time between WORKING reports of a robot still on the current tick.
HEARTBEAT = 1.0
#: [s] wall time between looks for robots that may join.
JOIN_PERIOD = 0.2
#: [s] wall time a robot waits for the inputs of a tick before it goes on without them.
INPUT_TIMEOUT = 5.0


class LockstepRobot(Protocol):
    @property
    def robot_id(self) -> int:
        """The robot's id (robots work a tick in id order)."""

    def joinable(self) -> bool:
        """Ready to take part (built, its pose heard)."""

    def roster(self, tick: Tick) -> None:
        """The tick's members are known (executor thread): listen to each of them."""

    def missing(self, tick: Tick) -> list[str]:
        """What the tick still waits for (thread-safe)."""

    def step(self, tick: Tick) -> tuple[float, float] | None:
        """Work the tick (driver thread); the body's command, or None."""


class LockstepDriver:
    """See module docstring. ``host`` carries the process's tick subscription and report
    publisher; ``on_roster(tick)`` hooks run on each new tick before the robots' own (e.g. the
    container's state hub)."""

    def __init__(self, host: Node, robots: list[LockstepRobot],
                 warn: Callable[[str, str], object],
                 on_roster: Callable[[Tick], None] | None = None) -> None:
        self.host = host
        self.robots = sorted(robots, key=lambda r: r.robot_id)
        self._warn = warn
        self._on_roster = on_roster
        self.report_pub = host.create_publisher(LockstepReport, "/world/tick_report",
                                                REPORT_QOS)
        host.create_subscription(LockstepTick, "/world/tick", self._on_tick, TICK_QOS)
        self._cond = threading.Condition()
        self.latest: Tick | None = None
        self.done: dict[int, int] = {}  # robot id -> newest tick answered
        self._commands: dict[int, tuple[float, float] | None] = {}
        self._working: int | None = None  # robot id the thread works on
        self._last_beat = 0.0
        self._closed = False
        self.ticks = 0
        self.waited = 0.0  # [s] wall time spent waiting for inputs
        wall = Clock(clock_type=ClockType.STEADY_TIME)
        host.create_timer(JOIN_PERIOD, self._on_timer, clock=wall)
        self._thread = threading.Thread(target=self._loop, name="coverage-lockstep",
                                        daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ executor thread
    def notify(self) -> None:
        """An input arrived (any thread): the waiting tick looks again."""
        with self._cond:
            self._cond.notify_all()

    def _on_tick(self, msg: LockstepTick) -> None:
        tick = conv.tick_from_msg(msg)
        latest = self.latest
        if latest is not None and tick.index < latest.index:
            return  # an old tick re-sent
        if self._on_roster is not None:
            self._on_roster(tick)
        for robot in self.robots:
            if robot.robot_id in tick.robots:
                robot.roster(tick)
                if self.done.get(robot.robot_id) == tick.index:
                    self._report(DONE, tick.index, robot.robot_id,  # our answer was lost
                                 self._commands.get(robot.robot_id))
        with self._cond:
            self.latest = tick
            self._cond.notify_all()
        self._join(tick)

    def _on_timer(self) -> None:
        tick = self.latest
        if tick is None:
            return
        self._join(tick)
        now = time.monotonic()
        if now - self._last_beat >= HEARTBEAT:
            self._last_beat = now
            for robot in self.robots:
                rid = robot.robot_id
                if rid in tick.robots and self.done.get(rid, -1) < tick.index:
                    self._report(WORKING, tick.index, rid)

    def _join(self, tick: Tick) -> None:
        for robot in self.robots:
            if robot.robot_id not in tick.robots and robot.joinable():
                self._report(JOIN, tick.index, robot.robot_id)

    def _report(self, kind: int, tick: int, robot_id: int,
                command: tuple[float, float] | None = None) -> None:
        self.report_pub.publish(conv.report_msg(kind, tick, robot_id, command=command))

    # ------------------------------------------------------------------ driver thread
    def _next(self) -> tuple[Tick, LockstepRobot] | None:
        """The newest tick and the first robot (by id) listed at it that owes an answer."""
        tick = self.latest
        if tick is None:
            return None
        for robot in self.robots:
            if robot.robot_id in tick.robots and self.done.get(robot.robot_id, -1) < tick.index:
                return tick, robot
        return None

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._closed and (work := self._next()) is None:
                    self._cond.wait(0.5)
                if self._closed:
                    return
            assert work is not None  # (the loop above waits for one)
            first, robot = work
            tick = self._wait_inputs(first, robot)
            if tick is None:
                continue  # a newer tick came (the world went on without this robot)
            self._working = robot.robot_id
            try:
                command = robot.step(tick)
            except Exception as exc:  # a robot's bug must not stop the process's other robots
                if self._closed:
                    return
                self._warn(f"tick{robot.robot_id}", f"robot {robot.robot_id}: lock-step tick "
                           f"{tick.index} failed ({type(exc).__name__}: {exc}); standing still")
                command = (0.0, 0.0)
            finally:
                self._working = None
            self.done[robot.robot_id] = tick.index
            self._commands[robot.robot_id] = command
            self.ticks += 1
            if not self._closed:
                self._report(DONE, tick.index, robot.robot_id, command)

    def _wait_inputs(self, tick: Tick, robot: LockstepRobot) -> Tick | None:
        """Wait until ``robot``'s inputs of ``tick`` are in (or INPUT_TIMEOUT); the tick as
        last sent (the world sends it again without a robot that died meanwhile), or None if a
        newer tick arrived."""
        t0 = time.monotonic()
        with self._cond:
            while not self._closed:
                if self.latest is None or self.latest.index != tick.index:
                    return None
                tick = self.latest
                missing = robot.missing(tick)
                if not missing:
                    break
                waited = time.monotonic() - t0
                if waited >= INPUT_TIMEOUT:
                    self._warn(f"inputs{robot.robot_id}", f"robot {robot.robot_id}: tick "
                               f"{tick.index} (sim {tick.time:.2f} s) still lacks "
                               f"{', '.join(missing[:4])} after {waited:.1f} s: going on "
                               "without")
                    break
                self._cond.wait(0.5)
        self.waited += time.monotonic() - t0
        return None if self._closed else tick

    def close(self) -> None:
        """Stop the thread and tell the world the process's robots are leaving."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        self._thread.join(5.0)
        tick = self.latest
        for robot in self.robots:
            if tick is not None and robot.robot_id in tick.robots:
                try:
                    self._report(LEAVE, tick.index, robot.robot_id)
                except Exception:  # the context may be gone already
                    return

    def summary(self) -> str:
        return (f"lock-step: answered {self.ticks} robot ticks, {self.waited:.1f} s of wall "
                "time waiting for inputs")
