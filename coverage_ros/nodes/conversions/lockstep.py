"""Message conversions: lock-step ticks and reports (``coverage_msgs``; conventions:
:mod:`..conversions`). Sim time crosses as integer nanoseconds so that stamps compare exactly."""

from __future__ import annotations

from builtin_interfaces.msg import Time
from coverage_msgs.msg import LockstepReport, LockstepTick

from coverage_ros.core.lockstep import Tick, TickPlan


def stamp_ns(stamp: Time) -> int:
    """``builtin_interfaces/Time`` -> integer nanoseconds."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def ns_time_msg(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def tick_msg(plan: TickPlan, stamp: int, previous: int, period: float, scanned: list[int],
             status: bool) -> LockstepTick:
    """The world's tick ``plan`` at sim time ``stamp`` [ns]."""
    return LockstepTick(tick=plan.tick, stamp=ns_time_msg(stamp), previous=ns_time_msg(previous),
                        period=float(period), robots=list(plan.robots),
                        observers=list(plan.observers), answered=list(plan.answered),
                        scanned=sorted(scanned), status=bool(status))


def tick_from_msg(msg: LockstepTick) -> Tick:
    return Tick(index=int(msg.tick), stamp=stamp_ns(msg.stamp), previous=stamp_ns(msg.previous),
                period=float(msg.period), robots=frozenset(int(r) for r in msg.robots),
                observers=frozenset(str(o) for o in msg.observers),
                answered=tuple(int(r) for r in msg.answered),
                scanned=frozenset(int(r) for r in msg.scanned), status=bool(msg.status))


def report_msg(kind: int, tick: int, robot_id: int = -1, observer: str = "",
               command: tuple[float, float] | None = None) -> LockstepReport:
    msg = LockstepReport(kind=kind, robot_id=int(robot_id), observer=observer, tick=int(tick))
    if command is not None:
        msg.has_command = True
        msg.linear, msg.angular = float(command[0]), float(command[1])
    return msg
