"""Lock-step's two halves without ROS: the world's barrier (whom it waits for, when the next
tick goes, what it applies) and a member's inbox (which inputs belong to which tick)."""

from __future__ import annotations

import pytest

from coverage_ros.core.lockstep import Barrier, Inbox, Tick, observer, robot, ticks_per
from coverage_ros.core.lockstep.barrier import DONE, JOIN, LEAVE, WORKING
from coverage_ros.core.lockstep.inbox import EVIDENCE_KEY

MS = 1_000_000  # [ns]


def started(*robots: int, now: float = 0.0) -> Barrier:
    """A barrier past its first tick with ``robots`` as members."""
    b = Barrier(10.0, 60.0, expected_robots=robots, now=now)
    for r in robots:
        b.join(robot(r), 0, now)
    for r in robots:
        b.report(robot(r), DONE, 0, now, (0.0, 0.0))
    assert b.ready(now)
    b.advance(now)
    return b


def test_report_kinds_are_the_messages_constants():
    from coverage_msgs.msg import LockstepReport

    assert (JOIN, WORKING, DONE, LEAVE) == (LockstepReport.JOIN, LockstepReport.WORKING,
                                            LockstepReport.DONE, LockstepReport.LEAVE)


def test_the_first_tick_waits_for_every_expected_member_then_for_their_answers():
    b = Barrier(10.0, 60.0, expected_robots=[0, 1], expected_observers=["monitor"])
    assert b.join(robot(0), 0, 1.0) == (True, "robot 0 joined at tick 0")
    b.report(robot(0), DONE, 0, 1.0, (0.1, 0.0))
    assert not b.ready(2.0) and b.waiting_for_start(2.0) == [(-1, "monitor"), robot(1)]
    b.join(robot(1), 0, 2.0)
    b.join(observer("monitor"), 0, 2.0)
    assert b.robots == (0, 1) and b.observers == ("monitor",)
    assert not b.ready(2.0) and b.owing() == [(-1, "monitor"), robot(1)]
    b.report(robot(1), DONE, 0, 2.5, (0.2, 0.3))
    b.report(observer("monitor"), DONE, 0, 2.5)
    assert b.ready(2.5)
    plan = b.advance(2.5)
    assert (plan.tick, plan.robots, plan.observers, plan.answered) == (1, (0, 1), ("monitor",),
                                                                       (0, 1))
    assert plan.commands == {0: (0.1, 0.0), 1: (0.2, 0.3)}
    assert not b.ready(2.5)  # nobody answered tick 1 yet


def test_the_start_goes_without_missing_members_after_the_start_timeout():
    b = Barrier(10.0, 30.0, expected_robots=[0, 1], now=0.0)
    b.join(robot(0), 0, 1.0)
    b.report(robot(0), DONE, 0, 1.0)
    assert not b.ready(29.0)
    assert b.ready(31.0) and b.advance(31.0).robots == (0,)


def test_a_robot_without_a_body_is_not_admitted():
    b = Barrier(10.0, 0.0, has_body=lambda rid: rid < 2)
    assert b.join(robot(5), 0, 0.0)[1].startswith("robot 5 asked to join")
    assert b.join(robot(5), 0, 0.1) == (False, "")  # said once
    assert b.robots == () and not b.ready(1.0)  # no members: the world waits


def test_a_member_joining_later_is_listed_from_the_next_tick_and_its_state_is_not_due_yet():
    b = started(0)
    assert b.join(robot(1), 1, 1.0) == (False, "robot 1 joined: listed from tick 2")
    assert b.robots == (0,)
    b.report(robot(0), DONE, 1, 1.0, (0.0, 0.0))
    plan = b.advance(1.0)
    assert plan.robots == (0, 1) and plan.answered == (0,)


def test_answers_of_other_ticks_and_of_strangers_change_nothing():
    b = started(0, 1)
    b.report(robot(0), DONE, 0, 1.0)  # a repeated answer to tick 0
    b.report(robot(7), DONE, 1, 1.0)
    b.report(robot(0), WORKING, 1, 1.0)
    assert b.owing() == [robot(0), robot(1)]
    b.report(robot(0), DONE, 1, 1.0, (float("nan"), 0.0))  # a broken command stands still
    b.report(robot(1), DONE, 1, 1.0)
    assert b.advance(1.0).commands == {0: (0.0, 0.0)}


def test_a_joins_sent_before_the_member_saw_itself_listed_is_ignored_a_restart_is_not():
    b = started(0, 1)  # both admitted at tick 0; now at tick 1
    assert b.join(robot(1), 0, 1.0) == (False, "")  # an old JOIN still in flight
    assert b.owing() == [robot(0), robot(1)]
    changed, text = b.join(robot(1), 1, 1.5)  # a new process that has seen tick 1
    assert not changed and "joined again" in text
    assert b.owing() == [robot(0)]  # the old process's answer: stand still, no state
    b.report(robot(0), DONE, 1, 2.0, (0.1, 0.0))
    plan = b.advance(2.0)
    assert plan.commands == {0: (0.1, 0.0), 1: (0.0, 0.0)} and plan.answered == (0,)
    assert plan.robots == (0, 1) and b.owing() == [robot(0), robot(1)]


def test_a_silent_member_is_dropped_after_the_timeout_counted_from_the_tick_or_its_last_word():
    b = started(0, 1, now=0.0)
    b.report(robot(0), DONE, 1, 0.1)
    b.advance(20.0)  # tick 2 went out at 20 s (the world had waited for robot 1 all along)
    b.report(robot(0), DONE, 2, 20.1)
    assert b.expire(25.0) == []  # robot 1: 5 s since the tick, though 20 s since its last word
    b.report(robot(1), WORKING, 2, 28.0)  # a heartbeat
    assert b.expire(37.0) == []
    lines = b.expire(38.5)
    assert len(lines) == 1 and lines[0].startswith("robot 1 silent for 10.5 s at tick 2")
    assert b.ready(38.5) and b.advance(38.5).answered == (0,)


def test_a_member_that_keeps_reporting_working_holds_the_tick_and_the_line_names_it():
    """A long coverage update: heartbeats keep robot 1 listed past any silence timeout, and the
    world's line on the held tick names whom it waits for."""
    b = started(0, 1, 2, 3, 4, 5, 6, now=0.0)
    for r in (0, 2):
        b.report(robot(r), DONE, 1, 0.1)
    for t in range(5, 400, 5):
        b.report(robot(1), WORKING, 1, float(t))
        for r in (3, 4, 5, 6):
            b.report(robot(r), WORKING, 1, float(t))
        assert b.expire(float(t) + 1.0) == []
    assert not b.ready(400.0) and b.tick == 1
    assert b.held(400.0, shown=3) == ("tick 1 has waited 400 s of wall time for robot 1, "
                                      "robot 3, robot 4 and 2 more, still reporting: working "
                                      "on it")
    for r in (1, 3, 4, 5, 6):
        b.report(robot(r), DONE, 1, 401.0)
    assert b.ready(401.0) and b.advance(401.0).tick == 2


def test_a_member_dropped_after_answering_is_no_longer_waited_for_by_the_others():
    """Robot 1 answered tick 1 and died: tick 2 lists it among the robots whose states are due,
    but it may have died before its state went out - once it is dropped, the tick goes out
    again without it, so that nobody waits for that state."""
    b = started(0, 1, now=0.0)
    for r in (0, 1):
        b.report(robot(r), DONE, 1, 0.1, (0.0, 0.0))
    assert b.advance(0.1).answered == (0, 1) and b.answered == (0, 1)
    b.report(robot(0), DONE, 2, 0.2)
    assert b.expire(5.0) == [] and b.answered == (0, 1)
    assert len(b.expire(11.0)) == 1 and b.answered == (0,)
    b2 = started(0, 1, 2)
    for r in (0, 1, 2):
        b2.report(robot(r), DONE, 1, 0.0)
    b2.advance(0.0)
    b2.leave(robot(2))
    b2.remove_robot(1)
    assert b2.answered == (0,) and b2.robots == (0,)


def test_leave_and_removal_stop_the_wait():
    b = started(0, 1, 2)
    b.report(robot(0), DONE, 1, 1.0)
    assert b.leave(robot(1)) == "robot 1 left the lock-step at tick 1"
    assert not b.ready(1.0)
    b.remove_robot(2)
    assert b.ready(1.0) and b.advance(1.0).robots == (0,)


def tick(index: int, answered=(), scanned=(), robots=(0, 1, 2)) -> Tick:
    return Tick(index, index * 100 * MS, max(index - 1, 0) * 100 * MS, 0.1,
                frozenset(robots), frozenset(), tuple(answered), frozenset(scanned))


def test_the_inbox_hands_out_exactly_the_inputs_of_the_tick():
    box = Inbox(own_id=0)
    t3 = tick(3, answered=(0, 1, 2), scanned=(0,))
    assert box.missing(t3, scan=True) == ["pose", "scan", "state of robot 1", "state of robot 2"]
    box.put_pose(300 * MS, "pose@3")
    box.put_pose(400 * MS, "pose@4")  # (cannot come before tick 4, but must not be taken)
    box.put_scan(150 * MS, "scan@1.5")  # older than the tick before: no help, but handed out
    assert box.missing(t3, scan=True) == ["scan", "state of robot 1", "state of robot 2"]
    box.put_scan(300 * MS, "scan@3")
    box.put_state(1, 200 * MS, {"x": 1.0})
    box.put_state(1, 300 * MS, {"x": 1.5})  # robot 1 is one tick ahead: not for tick 3
    box.put_state(0, 200 * MS, {"x": 9.0})  # its own state comes back: ignored
    assert box.missing(t3, scan=True) == ["state of robot 2"]
    box.put_state(2, 200 * MS, {"x": 2.0})
    assert box.missing(t3, scan=True) == []
    got = box.take(t3)
    assert got.pose == "pose@3" and got.scans == [(150 * MS, "scan@1.5"), (300 * MS, "scan@3")]
    assert got.states == {1: {"x": 1.0}, 2: {"x": 2.0}}
    t4 = tick(4, answered=(1, 2))
    assert box.missing(t4) == ["state of robot 2"]  # robot 1's state of tick 3 was kept
    assert box.take(t4).pose == "pose@4"


def test_a_tick_without_a_scan_due_or_with_a_robot_that_did_not_answer_waits_for_neither():
    box = Inbox(own_id=0)
    t = tick(5, answered=(0, 2), scanned=(1, 2))  # robot 1 did not answer tick 4
    box.put_pose(500 * MS, "p")
    box.put_state(2, 400 * MS, {"x": 0.0})
    assert box.missing(t, scan=True) == []


def test_evidence_is_waited_for_up_to_the_stamp_the_sender_names_and_no_further():
    box = Inbox(own_id=0)
    t2 = tick(2, answered=(1,))
    box.put_pose(200 * MS, "p")
    box.put_state(1, 100 * MS, {"x": 0.0, EVIDENCE_KEY: 0.1})
    assert box.missing(t2, evidence=True) == ["evidence of robot 1"]
    assert box.missing(t2) == []  # a robot that does not explore does not wait for it
    box.put_evidence(1, 100 * MS, "e@1")
    box.put_evidence(1, 200 * MS, "e@2")  # one tick ahead: kept for later
    assert box.missing(t2, evidence=True) == []
    assert [e for _, _, e in box.take(t2, evidence=True).evidence] == ["e@1"]
    t3 = tick(3, answered=(1,))
    box.put_pose(300 * MS, "p")
    box.put_state(1, 200 * MS, {"x": 0.0, EVIDENCE_KEY: 0.2})
    assert [e for _, _, e in box.take(t3, evidence=True).evidence] == ["e@2"]
    box.put_evidence(1, 100 * MS, "e@1 again")  # a repeat of what was merged: dropped
    box.put_state(1, 300 * MS, {"x": 0.0, EVIDENCE_KEY: 0.2})  # nothing new since
    t4 = tick(4, answered=(1,))
    box.put_pose(400 * MS, "p")
    assert box.missing(t4, evidence=True) == [] and box.take(t4, evidence=True).evidence == []


def test_states_of_the_first_tick_that_come_before_it_is_worked_on_are_kept_for_the_next():
    box = Inbox(own_id=2)
    t0 = tick(0)  # (its previous tick is itself)
    box.put_pose(0, "p0")
    box.put_state(0, 0, {"x": 0.0})  # robot 0 answered tick 0 before robot 2 took it
    box.take(t0)
    box.put_pose(100 * MS, "p1")
    t1 = tick(1, answered=(0, 2))
    assert box.missing(t1) == [] and box.take(t1).states == {0: {"x": 0.0}}


@pytest.mark.parametrize(("period", "tick_s", "every"), [(0.5, 0.1, 5), (0.1, 0.1, 1),
                                                          (0.05, 0.1, 1), (1 / 3, 0.1, 3)])
def test_rates_become_whole_numbers_of_ticks(period, tick_s, every):
    assert ticks_per(period, tick_s) == every


def test_something_due_every_five_ticks_comes_first_at_tick_one():
    assert [k for k in range(13) if tick(k).due(5)] == [1, 6, 11]
