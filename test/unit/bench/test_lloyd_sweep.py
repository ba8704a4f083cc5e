"""scripts/bench_planner's sweep summary: which targets a set of scenarios meets."""

from __future__ import annotations

from coverage_ros.bench.lloyd_sweep import summarize


def _row(steps_plain, steps_acc, within, gap):
    return {"plain": {"converged": True}, "accelerated": {"converged": True, "gap": gap},
            "ratio_steps": steps_acc / steps_plain, "ratio_within": within / steps_plain,
            "ratio_within_own": within / steps_plain}


def test_targets_follow_median_worst_and_gap():
    rows = [_row(100, 60, 40, 0.0), _row(100, 50, 45, -0.001), _row(100, 110, 70, -0.002)]
    met = summarize(rows)["targets_met"]
    assert met["median_within_0.1%_in_half_plain_steps"]  # median 45 / 100
    assert met["worst_case_within_0.1%_no_slower_than_plain"]  # worst 70 / 100
    assert not met["worst_case_no_slower_than_plain"]  # 110 steps to converge against 100
    assert met["never_more_than_0.1%_above_plain_H"]
    rows.append(_row(100, 90, 101, 0.0011))
    met = summarize(rows)["targets_met"]
    assert not met["never_more_than_0.1%_above_plain_H"]  # +0.11 %
    assert not met["worst_case_within_0.1%_no_slower_than_plain"]
    assert not met["median_within_0.1%_in_half_plain_steps"]  # median (45 + 70) / 2 / 100
