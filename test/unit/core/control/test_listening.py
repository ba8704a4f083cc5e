"""A robot's first update waits until it has listened for its team (core/control/listening)."""

from __future__ import annotations

from coverage_ros.core.control.listening import TeamListening


def test_without_a_team_size_a_robot_listens_for_the_first_period_only():
    t = TeamListening(first=1.5)
    assert t.listening(0.0, 0) == (False, "")  # no pose yet: nothing to wait for
    t.pose(10.0)
    t.pose(11.0)  # the first pose counts
    assert t.listening(11.4, 0)[0] and t.listening(11.49, 3)[0]
    assert t.listening(11.5, 0) == (False, "")
    assert t.listening(11.6, 0) == (False, "")


def test_with_a_team_size_a_robot_waits_for_every_teammate():
    t = TeamListening(first=1.5, team_size=4, timeout=10.0)
    t.pose(0.0)
    assert t.listening(1.6, 2)[0] and t.listening(5.0, 2)[0]
    assert t.listening(5.1, 3) == (False, "")
    assert t.listening(5.2, 1) == (False, "")  # once started, never waits again


def test_a_robot_whose_team_stays_silent_starts_after_the_timeout_with_a_warning():
    t = TeamListening(first=1.5, team_size=4, timeout=10.0)
    t.pose(0.0)
    assert t.listening(9.9, 1)[0]
    listening, warning = t.listening(10.0, 1)
    assert not listening and "heard 1 of the 3 other robots" in warning
    assert t.listening(10.1, 1) == (False, "")  # warned once
