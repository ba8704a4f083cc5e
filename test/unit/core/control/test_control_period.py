"""The control period a step is scaled by (coverage_ros/core/control/period.py)."""

import pytest

from coverage_ros.core.control.period import MAX_PERIOD_FACTOR, ControlPeriod


def test_the_period_is_measured_and_a_pause_falls_back_to_the_nominal_one():
    clock = ControlPeriod(0.2)
    assert clock.elapsed(10.0) == 0.2  # first update: nothing to measure yet
    assert clock.elapsed(10.25) == pytest.approx(0.25)
    assert clock.elapsed(10.25 + MAX_PERIOD_FACTOR * 0.2 + 0.01) == 0.2  # a pause
    assert clock.elapsed(10.0) == 0.2  # time ran backwards (a restarted /clock)
    assert clock.elapsed(10.1) == pytest.approx(0.1)
