"""The clock guard: a second simulation on the domain, or time going back
(coverage_ros/nodes/clock_guard.py)."""

from __future__ import annotations


def test_the_clock_guard_sees_a_second_clock_and_time_going_back():
    from coverage_ros.nodes.clock_guard import ClockGuard

    guard = ClockGuard(jump_back=1.0)
    assert guard.check_time(10.0) == guard.check_time(10.5) == ""
    assert guard.check_time(9.8) == ""  # jitter of a few clock periods is not a jump
    assert "went back from 10.5 s to 3.0 s" in guard.check_time(3.0)
    assert guard.check_publishers(1) == "" and "2 nodes publish /clock" in \
        guard.check_publishers(2)
