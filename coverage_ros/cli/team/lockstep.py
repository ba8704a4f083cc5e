"""The launcher's monitor as a lock-step observer (``coverage-team --lockstep``).

The monitor is a member of the world's barrier (observer ``coverage_team``): it answers every
tick, and the world waits for it, so whatever it measures at a tick - the robots' poses,
collisions and path lengths in the world's status of that tick, the coverage cost from them,
the explored share of the map from the evidence published up to the tick before - belongs to
that tick exactly, and the run ends at an exact tick: the same seed gives the same summary.
"""

from __future__ import annotations

import math
import time
from collections import deque
from functools import partial

from coverage_msgs.msg import LockstepReport, LockstepTick, RobotState

from coverage_ros.core.lockstep import Inbox, Tick
from coverage_ros.core.lockstep.barrier import DONE, JOIN, LEAVE, WORKING
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.qos import LOCKSTEP_STATE_QOS, REPORT_QOS, TICK_QOS, quiet_subscription
from coverage_ros.nodes.shm_ports import startup_hint

#: The monitor's member name (world_node's lockstep_observers).
OBSERVER = "coverage_team"
#: [s] wall time between the monitor's JOIN or WORKING reports.
BEAT = 0.5
#: [s] wall time a robot's WORKING report counts as news (robots send one every second; a
#: starved process may send them late).
WORKING_FRESH = 30.0


class LockstepObserver:
    """The monitor's side of the barrier. ``evidence``: an exploring team, whose evidence the
    monitor merges at the ticks it samples (``put_evidence(sender, stamp, evidence)`` of the
    monitor's exploration gets the messages; :meth:`inputs_missing` waits for them)."""

    def __init__(self, node, robot_ids: list[int], prefix: str = "robot_",
                 evidence: bool = False) -> None:
        self.node = node
        self.report_pub = node.create_publisher(LockstepReport, "/world/tick_report",
                                                REPORT_QOS)
        node.create_subscription(LockstepTick, "/world/tick", self._on_tick, TICK_QOS)
        # the robots' reports: which of them a tick that does not come waits for
        node.create_subscription(LockstepReport, "/world/tick_report", self._on_report,
                                 REPORT_QOS)
        #: robot id -> (tick, wall time [s]) of its newest WORKING report not yet followed
        #: by its DONE
        self.working: dict[int, tuple[int, float]] = {}
        self.last_working = -math.inf  # [s] wall time of the newest robot's WORKING report
        self._pending: deque[Tick] = deque()
        self.handled = -1  # newest tick answered
        self.listed = False  # the world lists the monitor
        self.status_stamp = -1  # [ns] of the newest /world/robots received
        self._beat = 0.0
        self.inbox = Inbox(-1) if evidence else None
        if evidence:
            for rid in robot_ids:
                node.create_subscription(
                    RobotState, f"/{prefix}{rid}/coverage_state",
                    partial(self._on_state, rid), LOCKSTEP_STATE_QOS,
                    event_callbacks=quiet_subscription())

    def _on_state(self, rid: int, msg: RobotState) -> None:
        try:
            values = conv.coverage_state_values(msg)
        except ValueError:
            return  # the robots warn about bad states themselves
        if self.inbox is not None:
            self.inbox.put_state(rid, conv.stamp_ns(msg.header.stamp), values)

    def put_evidence(self, sender: int, stamp: int, evidence: object) -> None:
        """Exploration evidence heard from ``sender``, stamped ``stamp`` [ns]."""
        if self.inbox is not None:
            self.inbox.put_evidence(sender, stamp, evidence)

    def _on_tick(self, msg: LockstepTick) -> None:
        tick = conv.tick_from_msg(msg)
        self.listed = OBSERVER in tick.observers
        if tick.index <= self.handled:
            if tick.index == self.handled and self.listed:
                self._report(DONE, tick.index)  # the answer may have been lost
            return
        if self._pending and self._pending[-1].index == tick.index:
            self._pending[-1] = tick  # the same tick again (members joined): the newest list
        else:
            self._pending.append(tick)

    def _report(self, kind: int, tick: int) -> None:
        self.report_pub.publish(conv.report_msg(kind, tick, observer=OBSERVER))

    def _on_report(self, msg: LockstepReport) -> None:
        rid = int(msg.robot_id)
        if rid < 0:
            return
        if msg.kind == WORKING:
            self.working[rid] = (int(msg.tick), time.monotonic())
            if int(msg.tick) >= self.handled:
                self.last_working = self.working[rid][1]
        elif msg.kind in (DONE, LEAVE):
            self.working.pop(rid, None)

    def working_on(self, now: float) -> list[int]:
        """Robots that reported within :data:`WORKING_FRESH` that they still work on the tick
        the monitor answered last (the one the world holds), sorted."""
        return sorted(rid for rid, (tick, at) in self.working.items()
                      if tick >= self.handled and now - at <= WORKING_FRESH)

    def beat(self) -> None:
        """JOIN until listed; then WORKING while a tick is held (call often)."""
        now = time.monotonic()
        if now - self._beat < BEAT:
            return
        self._beat = now
        newest = self._pending[-1].index if self._pending else max(self.handled, 0)
        if not self.listed:
            self._report(JOIN, newest)
        elif self._pending:
            self._report(WORKING, self._pending[0].index)

    def next_tick(self) -> Tick | None:
        """The oldest tick not answered yet whose status (when it has one) has arrived."""
        if not self._pending or not self.listed:
            return None
        tick = self._pending[0]
        if tick.status and self.status_stamp < tick.stamp:
            return None
        return tick

    def inputs_missing(self, tick: Tick) -> list[str]:
        """Exploring: what the evidence of the tick before ``tick`` still waits for."""
        if self.inbox is None:
            return []
        return self.inbox.missing(tick, pose=False, states=True, evidence=True)

    def take_evidence(self, tick: Tick) -> list:
        """The evidence stamped up to the tick before ``tick`` (exploring)."""
        if self.inbox is None:
            return []
        return [e for _, _, e in self.inbox.take(tick, evidence=True).evidence]

    def answer(self, tick: Tick) -> None:
        """``tick`` is handled: DONE, and on to the next."""
        if self._pending and self._pending[0].index == tick.index:
            self._pending.popleft()
        self.handled = tick.index
        self._report(DONE, tick.index)


#: [s] sim time between the coverage cost samples of a lock-step run (H_series).
METRICS_PERIOD = 5.0
#: [s] sim time between scores of an exploring team's merged belief.
EXPLORE_PERIOD = 1.0
#: [s] wall time the monitor waits for the evidence of a sampled tick before scoring without.
EVIDENCE_TIMEOUT = 10.0
#: [s] wall time between looks at the launcher's children (whether one exited).
CHECK_PERIOD = 0.2
#: [s] wall time without a new tick, and without a robot's report that it works on the tick,
#: after which a started team is given up (the world drops a silent robot after 10 s: a stuck
#: world or a lost link to it; counted from the last such report, as the world takes a moment
#: to step once the last robot is done).
STALL_TIMEOUT = 300.0
#: [s] wall time a tick is waited for while robots report working on it (a long coverage update:
#: a closet escape pricing moves on a large map, on a crowded host, takes minutes); past it the
#: team is given up, naming them.
HELD_TIMEOUT = 3600.0
#: [s] wall time between the lines that say which robots a held tick waits for.
HELD_NOTICE = 60.0


def run_lockstep(monitor, observer: LockstepObserver, startup_timeout: float,
                 progress_period: float) -> None:
    """:meth:`~coverage_ros.cli.team.monitor.TeamMonitor.run` of a lock-step team: every
    sample at a tick of its own (module docstring); returns at the end tick, unanswered, so
    the world stands still at it while the launcher stops the team."""
    import rclpy

    log = monitor.log
    t0 = time.monotonic()
    monitor.say("  waiting for the world and the robots (lock-step) ...")
    end = next_metrics = next_explore = math.inf
    ready: float | None = None  # [s] sim time the team was ready
    last_progress = last_check = 0.0
    last_tick = last_notice = t0  # [s] wall time the last tick arrived, the last held line
    while True:
        rclpy.spin_once(monitor, timeout_sec=0.02)
        observer.beat()
        now = time.monotonic()
        if now - last_check >= CHECK_PERIOD:  # (the loop turns once per message)
            last_check = now
            monitor.check_children(starting=log.ready_at is None)
        if monitor.proc_stats is not None:
            monitor.proc_stats.sample(now)
        tick = observer.next_tick()
        if tick is not None and log.ready_at is None and tick.index > 0:
            raise RuntimeError(f"the world started without robots "
                               f"{sorted(set(monitor.alive()) - tick.robots)}")
        if tick is None:
            if log.ready_at is None and now - t0 > startup_timeout:
                raise RuntimeError(f"the world's lock-step did not list robots "
                                   f"{sorted(set(monitor.alive()))} within "
                                   f"{startup_timeout:g} s (see their logs){startup_hint()}")
            if ready is not None:
                last_notice = _held(monitor, observer, now, now - last_tick, last_notice)
            continue
        last_tick = now
        log.sim_time = max(log.sim_time, tick.time)
        if ready is None:
            if not set(monitor.alive()) <= tick.robots:
                # Tick 0 while the team joins: unanswered, the world does not start (nor does
                # it after its own start timeout: it waits for this answer).
                if time.monotonic() - t0 > startup_timeout:
                    raise RuntimeError(f"the world's lock-step did not list robots "
                                       f"{sorted(set(monitor.alive()) - tick.robots)} within "
                                       f"{startup_timeout:g} s (see their logs){startup_hint()}")
                continue
            monitor.team_ready(t0)
            ready = log.sim_time
            end = monitor.end
            next_metrics = ready + METRICS_PERIOD
            next_explore = ready
        t = tick.time
        monitor.apply_faults(t - ready, slack=1e-9)
        if tick.status and t >= next_metrics - 1e-9:
            next_metrics += METRICS_PERIOD
            log.H_samples.append((t, monitor.cost()))
            if monitor.settle is not None:
                _wait_states(monitor, observer, tick)
                if monitor.settled_enough(t, upto=tick.previous * 1e-9):
                    return
        if monitor.exploration is not None and tick.status and t >= next_explore - 1e-9:
            next_explore += EXPLORE_PERIOD
            _wait_evidence(monitor, observer, tick)
            for evidence in observer.take_evidence(tick):
                monitor.exploration.belief.merge(evidence)
            fraction = monitor.exploration.sample(t - ready)
            if monitor.explored_enough(fraction, monitor.config.until_explored):
                return
        if tick.status and t >= end - 1e-9:
            return  # the end: not answered, the world holds still here
        observer.answer(tick)
        now = time.monotonic()
        if now - last_progress >= progress_period:
            last_progress = now
            monitor.progress()


def _held(monitor, observer: LockstepObserver, now: float, held: float,
          last_notice: float) -> float:
    """A tick that has not come for ``held`` [s] of wall time: a line every
    :data:`HELD_NOTICE` naming the robots it waits for, RuntimeError once it is given up
    (:data:`STALL_TIMEOUT`, :data:`HELD_TIMEOUT`); returns when the last line was said."""
    working = observer.working_on(now)
    sim = monitor.log.sim_time
    if min(held, now - observer.last_working) > STALL_TIMEOUT:
        raise RuntimeError(f"the world's lock-step made no tick for {held:.0f} s of wall time "
                           f"after sim time {sim:.2f} s, and no robot has reported working on "
                           f"it for {STALL_TIMEOUT:g} s (see the world's log)")
    if held > HELD_TIMEOUT:
        raise RuntimeError(f"the world's lock-step made no tick for {HELD_TIMEOUT:g} s of "
                           f"wall time after sim time {sim:.2f} s while robots {working} "
                           "reported working on their update (see their logs)")
    if held >= HELD_NOTICE and now - last_notice >= HELD_NOTICE:
        who = f"robots {working}" if working else "no robot"
        monitor.say(f"\n  sim time {sim:.2f} s: no tick for {held:.0f} s of wall time; "
                    f"{who} reported working on it")
        return now
    return last_notice


def _wait_states(monitor, observer: LockstepObserver, tick: Tick) -> None:
    """--until-settled: wait until the monitor has heard the states stamped at the tick before
    ``tick`` from every living robot that answered it (those published before the answers),
    so that the settle check at ``tick`` rests on the same states in every run."""
    import rclpy

    t0 = time.monotonic()
    previous = tick.previous * 1e-9
    while missing := [rid for rid in tick.answered if rid in monitor.alive()
                      and monitor.settle.heard_up_to(rid) < previous]:
        if time.monotonic() - t0 > EVIDENCE_TIMEOUT:
            monitor.say(f"\n  tick {tick.index}: settle check without the states of robots "
                        f"{missing}")
            return
        rclpy.spin_once(monitor, timeout_sec=0.02)
        observer.beat()


def _wait_evidence(monitor, observer: LockstepObserver, tick: Tick) -> None:
    import rclpy

    t0 = time.monotonic()
    while missing := observer.inputs_missing(tick):
        if time.monotonic() - t0 > EVIDENCE_TIMEOUT:
            monitor.say(f"\n  tick {tick.index}: scoring without {', '.join(missing[:3])}")
            return
        rclpy.spin_once(monitor, timeout_sec=0.02)
        observer.beat()
