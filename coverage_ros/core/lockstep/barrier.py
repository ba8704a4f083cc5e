"""The world's side of lock-step simulation: whom it waits for at each tick, and when the next
tick may go (:class:`Barrier`).

Members are robots (by id; a robot member drives the body of that id) and observers (by name,
e.g. the team launcher's monitor). Their reports are those of ``coverage_msgs/LockstepReport``:

* JOIN - before the start, a member is listed at tick 0 at once; afterwards from the next tick
  on. A JOIN from a member already listed that has seen a newer tick than the one it was
  admitted at comes from a new process of it (a restart): its old process is gone, so it
  counts as answered (a standstill command, no state) and the new one is admitted next tick.
* WORKING - alive: restarts the member's silence timeout.
* DONE - answered the current tick (with the body's command, for a robot that drives).
* LEAVE - gone: it is waited for no more.

The first tick goes out once every expected member joined (the bodies' robots and the named
observers), or ``start_timeout`` passed with at least one member. A member that owes an answer
and has been silent for ``timeout`` (since its last report or since the tick went out, whichever
is later) is dropped, with one line; it may join again. Times are wall-clock seconds
(``time.monotonic``): only dead processes are judged by them, never the simulation.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

#: Report kinds (the constants of coverage_msgs/LockstepReport).
JOIN, WORKING, DONE, LEAVE = 0, 1, 2, 3

#: A member: ``(robot id, "")`` or ``(-1, observer name)``.
Member = tuple[int, str]


def robot(robot_id: int) -> Member:
    return (int(robot_id), "")


def observer(name: str) -> Member:
    return (-1, str(name))


def describe(member: Member) -> str:
    return f"robot {member[0]}" if member[0] >= 0 else f"observer {member[1]!r}"


@dataclass
class _Answer:
    command: tuple[float, float] | None  # [m/s, rad/s] for the body; None: keep cmd_vel
    has_state: bool  # its coverage_state stamped with the tick is out (robots)


@dataclass
class _Slot:
    admitted: int  # the first tick it was listed at
    heard: float  # [s] wall time of its last report
    answer: _Answer | None = None


@dataclass(frozen=True)
class TickPlan:
    """The tick to publish next: its members, the robots whose states it makes due, and the
    commands to apply before stepping to it (by robot id)."""

    tick: int
    robots: tuple[int, ...]
    observers: tuple[str, ...]
    answered: tuple[int, ...]
    commands: dict[int, tuple[float, float]] = field(default_factory=dict)


class Barrier:
    """See module docstring. ``has_body(robot_id)`` says whether the world simulates that
    robot: a robot without a body is not admitted (it would wait for a pose for ever)."""

    def __init__(self, timeout: float, start_timeout: float,
                 expected_robots: Iterable[int] = (), expected_observers: Iterable[str] = (),
                 now: float = 0.0, has_body: Callable[[int], bool] = lambda rid: True) -> None:
        if not (math.isfinite(timeout) and timeout > 0):
            raise ValueError(f"timeout must be > 0 [s], got {timeout!r}")
        if not (start_timeout >= 0):
            raise ValueError(f"start_timeout must be >= 0 [s], got {start_timeout!r}")
        self.timeout = float(timeout)
        self.start_timeout = float(start_timeout)
        self.expected = {robot(r) for r in expected_robots} | \
            {observer(n) for n in expected_observers}
        self.has_body = has_body
        self.created = now
        self.opened = now  # [s] wall time the current tick went out
        self.tick = 0
        self.started = False
        #: Robots whose states of the tick before the current one are due (see TickPlan); a
        #: member dropped meanwhile leaves it: nobody is to wait for a state it may never send.
        self.answered: tuple[int, ...] = ()
        self._members: dict[Member, _Slot] = {}
        self._joining: set[Member] = set()
        self._refused: set[int] = set()

    # ------------------------------------------------------------------ views
    @property
    def robots(self) -> tuple[int, ...]:
        return tuple(sorted(m[0] for m in self._members if m[0] >= 0))

    @property
    def observers(self) -> tuple[str, ...]:
        return tuple(sorted(m[1] for m in self._members if m[0] < 0))

    def owing(self) -> list[Member]:
        """Members that have not answered the current tick, sorted."""
        return sorted(m for m, s in self._members.items() if s.answer is None)

    def held(self, now: float, shown: int = 5) -> str:
        """A line on how long the current tick has waited at wall time ``now`` [s] and for
        whom (the first ``shown`` members owing)."""
        owing = self.owing()
        names = ", ".join(describe(m) for m in owing[:shown]) or "no member"
        more = f" and {len(owing) - shown} more" if len(owing) > shown else ""
        return (f"tick {self.tick} has waited {now - self.opened:.0f} s of wall time for "
                f"{names}{more}, still reporting: working on it")

    def is_member(self, member: Member) -> bool:
        return member in self._members

    # ------------------------------------------------------------------ reports
    def join(self, member: Member, seen_tick: int, now: float) -> tuple[bool, str]:
        """A JOIN; ``(the current tick's members changed, a line to log or '')``."""
        if member[0] >= 0 and not self.has_body(member[0]):
            if member[0] in self._refused:
                return False, ""
            self._refused.add(member[0])
            return False, (f"{describe(member)} asked to join the lock-step but the world has no "
                           "such robot: ignored")
        self._refused.discard(member[0])
        slot = self._members.get(member)
        if slot is not None:
            if seen_tick <= slot.admitted or member in self._joining:
                slot.heard = now
                return False, ""  # sent before it saw itself listed
            # A new process of a member listed since an older tick: the old one is gone.
            if slot.answer is None:
                slot.answer = _Answer((0.0, 0.0), has_state=False)
            self._joining.add(member)
            return False, (f"{describe(member)} joined again (a new process): listed from the "
                           "next tick")
        if not self.started or not self._members:
            self._members[member] = _Slot(self.tick, now)
            return True, f"{describe(member)} joined at tick {self.tick}"
        if member not in self._joining:
            self._joining.add(member)
            return False, f"{describe(member)} joined: listed from tick {self.tick + 1}"
        return False, ""

    def report(self, member: Member, kind: int, tick: int, now: float,
               command: tuple[float, float] | None = None) -> None:
        """A WORKING or DONE report (others: :meth:`join`, :meth:`leave`). Reports of other
        ticks than the current one, or from non-members, change nothing."""
        slot = self._members.get(member)
        if slot is None:
            return
        slot.heard = max(slot.heard, now)
        if kind == DONE and tick == self.tick and slot.answer is None:
            if command is not None and not all(math.isfinite(v) for v in command):
                command = (0.0, 0.0)
            slot.answer = _Answer(command, has_state=member[0] >= 0)

    def leave(self, member: Member) -> str:
        self._joining.discard(member)
        if self._members.pop(member, None) is None:
            return ""
        self._forget(member)
        return f"{describe(member)} left the lock-step at tick {self.tick}"

    def _forget(self, member: Member) -> None:
        self.answered = tuple(r for r in self.answered if r != member[0])

    def remove_robot(self, robot_id: int) -> str:
        """The body of ``robot_id`` is gone: its robot is waited for no more."""
        return self.leave(robot(robot_id))

    def expire(self, now: float) -> list[str]:
        """Drop the members that owe an answer and have been silent for ``timeout``."""
        lines = []
        for member in self.owing():
            slot = self._members[member]
            silent = now - max(slot.heard, self.opened)
            if silent > self.timeout:
                del self._members[member]
                self._joining.discard(member)
                self._forget(member)
                lines.append(f"{describe(member)} silent for {silent:.1f} s at tick {self.tick}: "
                             "no longer waited for (lockstep_timeout); it may join again")
        return lines

    # ------------------------------------------------------------------ ticks
    def waiting_for_start(self, now: float) -> list[Member]:
        """Expected members not joined yet, while the start waits for them (else [])."""
        if self.started or now - self.created >= self.start_timeout:
            return []
        return sorted(self.expected - set(self._members))

    def ready(self, now: float) -> bool:
        """Whether the next tick may go: there are members and every one answered (before the
        start, also every expected member joined or the start timeout passed)."""
        if not self._members or self.owing():
            return False
        return self.started or not self.waiting_for_start(now)

    def advance(self, now: float) -> TickPlan:
        """The next tick (call when :meth:`ready`)."""
        answered, commands = [], {}
        for member, slot in sorted(self._members.items()):
            if member[0] < 0 or slot.answer is None:
                continue
            if slot.answer.has_state:
                answered.append(member[0])
            if slot.answer.command is not None:
                commands[member[0]] = slot.answer.command
        self.tick += 1
        self.started = True
        self.opened = now
        self.answered = tuple(answered)
        for member in self._joining:
            self._members[member] = _Slot(self.tick, now)
        self._joining.clear()
        for slot in self._members.values():
            slot.answer = None
        return TickPlan(self.tick, self.robots, self.observers, tuple(answered), commands)
