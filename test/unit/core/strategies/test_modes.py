"""Every strategy's modes have a code, as robots send them
(coverage_ros/core/strategies/base.py)."""

from __future__ import annotations

from coverage_ros.core.strategies.base import MODES, mode_code, mode_name
from coverage_ros.core.strategies.tangentbug.bug import BugMode


def test_every_strategy_mode_has_a_code():
    assert all(m.value in MODES for m in BugMode)
    assert mode_name(mode_code("greedy")) == "greedy" and mode_code("nonsense") == -1
    assert mode_name(-1.0) == "" and mode_name(float("nan")) == "" and mode_name(99.0) == ""
