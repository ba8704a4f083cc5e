"""coverage-team --until-settled: when a team counts as settled."""

from __future__ import annotations

from coverage_msgs.msg import AcvtState, HandoverState, RobotState

from coverage_ros.cli.team.settling import SettleWatch, h_flat_since, moving_between_cells


def state(mode: int = RobotState.MODE_LLOYD, claim: int = -1, grant: int = -1,
          relocating: bool | None = None) -> RobotState:
    msg = RobotState(mode=mode)
    if claim >= 0 or grant >= 0:
        msg.handover = [HandoverState(claim=claim, grant=grant)]
    else:
        msg.handover = [HandoverState(claim=-1, grant=-1)]
    if relocating is not None:
        msg.acvt = [AcvtState(relocating=relocating)]
    return msg


def test_a_robot_moves_between_cells_while_it_claims_grants_relocates_or_has_not_started():
    assert not moving_between_cells(state())
    assert not moving_between_cells(state(relocating=False))
    assert moving_between_cells(state(claim=3))
    assert moving_between_cells(state(grant=0))
    assert moving_between_cells(state(mode=RobotState.MODE_RELOCATE))
    assert moving_between_cells(state(mode=RobotState.MODE_NONE))
    assert moving_between_cells(state(relocating=True))


def test_h_is_flat_only_over_a_whole_window_within_the_band():
    samples = [(0.0, 300.0), (10.0, 120.0), (20.0, 101.0), (30.0, 100.5), (40.0, 100.0)]
    assert h_flat_since(samples, 40.0, 20.0)  # 101 .. 100: within 1 %
    assert not h_flat_since(samples, 40.0, 30.0)  # 120 is in the window
    assert not h_flat_since(samples, 40.0, 50.0)  # no sample before the window: not known
    assert not h_flat_since(samples, 40.0, 20.0, band=0.005)
    assert not h_flat_since([], 40.0, 20.0)


def test_a_team_is_settled_once_nobody_has_moved_between_cells_for_the_window():
    watch = SettleWatch(window=20.0)
    flat = [(t, 100.0) for t in range(0, 101, 10)]
    assert not watch.settled(flat, 50.0, [0, 1])  # nobody heard yet
    watch.note(0, state(), 1.0)
    assert not watch.settled(flat, 50.0, [0, 1])  # robot 1 not heard yet
    watch.note(1, state(claim=0), 35.0)
    watch.note(0, state(grant=1), 35.0)
    watch.note(1, state(mode=RobotState.MODE_RELOCATE), 40.0)
    watch.note(1, state(), 45.0)
    assert not watch.settled(flat, 50.0, [0, 1])  # moved 10 s ago
    assert watch.settled(flat, 60.0, [0, 1])  # 20 s since the move ended
    assert watch.settled(flat, 58.0, [0])  # robot 1 killed: only robot 0 counts
    watch.note(0, state(mode=RobotState.MODE_NONE), 70.0)  # restarted
    assert not watch.settled(flat, 80.0, [0, 1])
    rising = flat[:-2] + [(90.0, 100.0), (100.0, 102.0)]
    assert not watch.settled(rising, 100.0, [0, 1])


def test_a_lock_step_check_counts_only_the_states_stamped_up_to_the_tick_before():
    """In lock-step the states of the tick being checked may or may not have arrived: the
    check at ``now`` rests on those stamped up to ``upto`` alone, so it decides the same in
    every run."""
    flat = [(t, 100.0) for t in range(0, 101, 10)]
    early, late = SettleWatch(window=20.0), SettleWatch(window=20.0)
    for watch in (early, late):
        watch.note(0, state(), 10.0)
        watch.note(1, state(), 10.0)
    early.note(1, state(claim=0), 60.0)  # the checked tick's own state, already here
    for watch in (early, late):
        assert watch.settled(flat, 60.0, [0, 1], upto=59.9)
        assert watch.heard_up_to(0) == 10.0
    assert early.heard_up_to(1) == 60.0 and late.heard_up_to(2) == float("-inf")
    late.note(1, state(claim=0), 60.0)
    for watch in (early, late):  # at the next check the claim counts in both
        assert not watch.settled(flat, 60.1, [0, 1], upto=60.0)
    robot_2 = SettleWatch(window=20.0)
    robot_2.note(2, state(), 61.0)  # heard, but only after the states the check may use
    assert not robot_2.settled(flat, 61.0, [2], upto=60.0)
    assert robot_2.settled(flat, 90.0, [2], upto=89.0)
