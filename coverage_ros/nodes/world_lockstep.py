"""world_node's lock-step mode (``lockstep: true``): the simulation waits for its clients.

Sim time advances by one ``lockstep_period`` only when every member of the barrier
(:class:`~coverage_ros.core.lockstep.Barrier`) has answered the current tick on
``/world/tick_report``. Then the world applies the members' commands (in robot id order), steps
the physics, publishes what belongs to the new instant - the scans as they are taken, then
``/clock``, every robot's odom and ground truth, ``/tf``, ``/world/robots`` every
``status_rate_hz`` of sim time - and last the tick itself on ``/world/tick``
(``coverage_msgs/LockstepTick``).

While it waits, the world re-publishes the current tick and what went out with it every
:data:`RESEND` seconds of wall time: a member whose subscriptions matched late, or a message
lost on the way, costs a second, not the run. ``real_time_factor`` > 0 is an upper bound on the
pace (0: as fast as the members answer).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from coverage_msgs.msg import LockstepReport, LockstepTick
from rclpy.clock import Clock, ClockType

from coverage_ros.core.lockstep import Barrier, TickPlan, observer, robot, ticks_per
from coverage_ros.core.lockstep.barrier import DONE, JOIN, LEAVE
from coverage_ros.errors import ConfigError
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.qos import REPORT_QOS, TICK_QOS

#: [s] wall time between re-publications of the current tick while the world waits.
RESEND = 1.0
#: [s] wall time between looks at the barrier (timeouts, the start, pacing).
POLL = 0.01
#: [s] wall time a tick waits for members still working before the log says which, and again
#: every as long after (a coverage update that long is waited for, its robot is not silent).
HELD_LOG = 60.0


@dataclass(frozen=True)
class LockstepConfig:
    """The world node's lock-step parameters (README "world_node")."""

    period: float = 0.1  # [s] sim time per tick
    timeout: float = 10.0  # [s] wall time a silent member is waited for
    start_timeout: float = 120.0  # [s] wall time the first tick waits for every body's robot
    observers: tuple[str, ...] = ()  # observer members the first tick waits for

    def check(self, physics_dt: float) -> int:
        """Physics steps per tick; ConfigError unless the period is a whole number of them."""
        steps = round(self.period / physics_dt)
        if steps < 1 or abs(steps * physics_dt - self.period) > 1e-9:
            raise ConfigError.at("lockstep_period", "must be a whole number of physics steps "
                                 f"({physics_dt:g} s)", self.period)
        for name in ("timeout", "start_timeout"):
            if not getattr(self, name) > 0:
                raise ConfigError.at(f"lockstep_{name}", "must be > 0 [s]", getattr(self, name))
        return steps


@dataclass
class _Sent:
    """What went out with the current tick (re-published while waiting)."""

    scans: list = field(default_factory=list)  # (robot id, LaserScan)
    status: object = None
    tick: LockstepTick | None = None
    at: float = 0.0  # [s] wall time


class WorldLockstep:
    """The lock-step side of a world node (see module docstring). ``node`` is the
    :class:`~coverage_ros.nodes.world_node.WorldNode`."""

    def __init__(self, node, config: LockstepConfig) -> None:
        self.node, self.config = node, config
        self.steps_per_tick = config.check(node.config.sim.dt)
        self.status_every = ticks_per(1.0 / node.config.status_rate_hz, config.period)
        self.barrier = Barrier(config.timeout, config.start_timeout,
                               expected_robots=sorted(node.sim.robots),
                               expected_observers=config.observers, now=time.monotonic(),
                               has_body=lambda rid: rid in node.sim.robots)
        self.tick_pub = node.create_publisher(LockstepTick, "/world/tick", TICK_QOS)
        node.create_subscription(LockstepReport, "/world/tick_report", self._on_report,
                                 REPORT_QOS)
        self.sent = _Sent()
        self._stamp = self._previous = self._now_ns()
        self._scanned: set[int] = set()
        self._anchor: tuple[float, float] | None = None  # (wall, sim) once started
        self._said_waiting = 0.0
        self._said_held = 0.0  # [s] wall time of the last line on a held tick
        node.create_timer(POLL, self._poll, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._publish_tick(TickPlan(0, (), (), ()), status=True)

    def _now_ns(self) -> int:
        return conv.stamp_ns(conv.to_time_msg(self.node.sim.time))

    def _log(self, text: str, warn: bool = False) -> None:
        if not text:
            return
        # (two call sites: rclpy refuses one call site logging at two severities)
        if warn:
            self.node.get_logger().warning(text)
        else:
            self.node.get_logger().info(text)

    # ------------------------------------------------------------------ reports
    def _on_report(self, msg: LockstepReport) -> None:
        member = robot(msg.robot_id) if msg.robot_id >= 0 else observer(msg.observer)
        now = time.monotonic()
        b = self.barrier
        if msg.kind == JOIN:
            changed, text = b.join(member, int(msg.tick), now)
            self._log(text)
            if changed:  # listed at the current tick at once: tell it
                self._publish_tick(self._current_plan(), status=self.sent.status is not None,
                                   again=True)
        elif msg.kind == LEAVE:
            self._log(b.leave(member))
            if self._forgotten() and not self._try_advance(now):
                self._resend(now)
        else:
            command = (msg.linear, msg.angular) if msg.has_command else None
            b.report(member, msg.kind, int(msg.tick), now, command)
            if msg.kind == DONE:
                self._try_advance(now)

    def robot_removed(self, robot_id: int) -> None:
        self._log(self.barrier.remove_robot(robot_id))
        now = time.monotonic()
        if not self._try_advance(now) and self._forgotten():
            self._resend(now)

    # ------------------------------------------------------------------ ticks
    def _poll(self) -> None:
        now = time.monotonic()
        for text in self.barrier.expire(now):
            self._log(text, warn=True)
        if not self._try_advance(now) and (now - self.sent.at >= RESEND or self._forgotten()):
            self._resend(now)
            self._say_held(now)

    def _say_held(self, now: float) -> None:
        b = self.barrier
        if b.started and now - b.opened >= HELD_LOG and now - self._said_held >= HELD_LOG:
            self._said_held = now
            self._log(b.held(now))

    def _forgotten(self) -> bool:
        """Whether a member dropped since the tick went out had answered the tick before (the
        others must stop waiting for its state: the tick goes out again without it)."""
        sent = self.sent.tick
        return sent is not None and tuple(sent.answered) != self.barrier.answered

    def _try_advance(self, now: float) -> bool:
        b = self.barrier
        if not b.ready(now):
            missing = b.waiting_for_start(now)
            if missing and now - self._said_waiting >= 10.0:
                self._said_waiting = now
                self._log(f"waiting for {len(missing)} members before the first tick, e.g. "
                          f"{', '.join(f'{m[0]}' if m[0] >= 0 else m[1] for m in missing[:5])}")
            return False
        rtf = self.node.config.real_time_factor
        if rtf > 0 and self._anchor is not None:
            wall0, sim0 = self._anchor
            if now < wall0 + (self.node.sim.time + self.config.period - sim0) / rtf:
                return False  # the poll timer comes back
        if not b.started:
            self._log(f"lock-step: first tick with robots {list(b.robots)}"
                      + (f" and observers {list(b.observers)}" if b.observers else ""))
        plan = b.advance(now)
        if self._anchor is None:
            self._anchor = (now, self.node.sim.time)
        self._step(plan)
        return True

    def _current_plan(self) -> TickPlan:
        b = self.barrier
        return TickPlan(b.tick, b.robots, b.observers, b.answered)

    def _step(self, plan: TickPlan) -> None:
        """Apply the commands, step one period, publish the new instant and the tick."""
        node = self.node
        for rid, (v, w) in plan.commands.items():
            if rid in node.sim.robots:
                try:
                    node.sim.set_command(rid, v, w)
                except ValueError as exc:
                    node._warn(f"cmd{rid}", f"robot {rid}: dropped a lock-step command: {exc}")
        self.sent = _Sent()
        self._scanned = set()
        self._previous = self._stamp
        for _ in range(self.steps_per_tick):
            for scan in node.sim.step():
                msg = node.publish_scan(scan)
                if msg is not None:
                    self.sent.scans.append((scan.robot_id, msg))
                    self._scanned.add(scan.robot_id)
            node.log_contacts()
        self._stamp = self._now_ns()
        node.publish_clock()
        node.publish_odometry()
        status = plan.tick % self.status_every == 0
        self._publish_tick(plan, status)

    def _publish_tick(self, plan: TickPlan, status: bool, again: bool = False) -> None:
        if status and not again:
            self.sent.status = self.node.publish_status()
        msg = conv.tick_msg(plan, self._stamp, self._previous, self.config.period,
                            sorted(self._scanned), status)
        self.sent.tick, self.sent.at = msg, time.monotonic()
        self.tick_pub.publish(msg)

    def _resend(self, now: float) -> None:
        """Everything of the current tick again (a member may have missed some of it)."""
        node = self.node
        node.publish_clock()
        node.publish_odometry()
        for rid, msg in self.sent.scans:
            io = node.io.get(rid)
            if io is not None:  # (not a robot removed meanwhile)
                io.scan_pub.publish(msg)
        if self.sent.status is not None:
            node.status_pub.publish(self.sent.status)
        tick = self._current_plan()
        self._publish_tick(tick, self.sent.status is not None, again=True)
        self.sent.at = now
