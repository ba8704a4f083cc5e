"""drive: false - the goal relay's rules: which coverage goals go to the robot's own navigator
(coverage_ros/core/control/goal_relay.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coverage_ros.core.control.goal_relay import GoalRelay


def test_goals_are_sent_again_only_when_they_moved():
    relay = GoalRelay(resend_distance=0.25)
    pose = np.array([0.0, 0.0, 0.0])
    first = relay.offer(np.array([1.0, 1.0]), pose)
    assert first is not None and first[2] == pytest.approx(math.pi / 4)  # heading of the way
    assert relay.offer(np.array([1.1, 1.1]), pose) is None  # 0.14 m: the navigator keeps it
    assert relay.offer(np.array([1.0, 1.24]), pose) is None
    moved = relay.offer(np.array([1.0, 1.3]), pose)  # 0.3 m from the goal sent: sent
    assert moved is not None and moved[:2] == pytest.approx([1.0, 1.3])
    assert relay.offer(np.array([1.0, 1.1]), pose) is None  # measured from the last one sent
    assert relay.offer(np.array([np.nan, 1.0]), pose) is None
    # At the goal already: the robot's own heading (no turn on the spot).
    here = GoalRelay(0.25).offer(np.array([2.0, 0.0]), np.array([2.0, 0.0, 1.0]))
    assert here[2] == pytest.approx(1.0)
    relay.reset()
    assert relay.offer(np.array([1.0, 1.3]), pose) is not None and relay.count == 3
