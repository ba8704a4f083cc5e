"""A robot's recent poses (coverage_ros/core/control/pose_history.py): the pose at a stamp and
the velocity over a window."""

from __future__ import annotations

import math

import pytest

from coverage_ros.core.control.pose_history import PoseHistory


def test_pose_history_interpolates_along_the_short_way():
    h = PoseHistory()
    assert h.at(1.0) is None and h.latest is None
    h.add(1.0, (0.0, 0.0, 3.0))
    h.add(2.0, (1.0, 2.0, -3.0))  # 0.28 rad counter-clockwise across +-pi
    x, y, yaw = h.at(1.5)
    assert (x, y) == pytest.approx((0.5, 1.0))
    assert abs(math.remainder(yaw - math.pi, 2 * math.pi)) < 1e-9
    assert h.at(2.3) == h.latest == (1.0, 2.0, -3.0)  # just after: the nearest sample
    assert h.at(5.0) is None  # too far from any sample
    h.add(1.5, (9.0, 9.0, 0.0))  # out of order: ignored
    assert h.at(1.5)[0] == pytest.approx(0.5)


def test_pose_history_velocity_is_the_mean_over_its_window():
    h = PoseHistory()
    assert h.velocity() == {}
    h.add(0.0, (1.0, 1.0, 0.0))
    h.add(0.01, (1.003, 1.004, 0.0))
    assert h.velocity() == {}  # two samples 10 ms apart: too short a span
    h = PoseHistory()
    for k in range(21):  # 1 s at 20 Hz, 0.5 m/s along (0.6, 0.8), then 0.5 s standing
        t = 0.05 * k
        h.add(t, (1.0 + 0.3 * t, 1.0 + 0.4 * t, 0.9))
    v = h.velocity()
    assert (v["vx"], v["vy"]) == pytest.approx((0.3, 0.4))
    for k in range(1, 11):
        h.add(1.0 + 0.05 * k, (1.3, 1.4, 0.9))
    assert (h.velocity()["vx"], h.velocity()["vy"]) == pytest.approx((0.0, 0.0))
    # 0.1 s into the stop, the mean over the last 0.3 s: 0.2 s of motion in it
    h = PoseHistory()
    for k in range(21):
        h.add(0.05 * k, (0.3 * 0.05 * k, 0.0, 0.0))
    h.add(1.1, (0.3, 0.0, 0.0))
    assert h.velocity()["vx"] == pytest.approx(0.3 * (1.0 - 0.8) / 0.3)
