"""scripts/bench_planner's sweep summary: which targets a set of scenarios meets."""

from __future__ import annotations

import numpy as np

from coverage_ros.bench.lloyd_sweep import NUDGE, nudged, scenario, summarize


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
    assert summarize(rows)["above_0.1%"] == 0
    rows.append(_row(100, 90, 101, 0.0011))
    summary = summarize(rows)
    met = summary["targets_met"]
    assert not met["never_more_than_0.1%_above_plain_H"]  # +0.11 %
    assert summary["above_0.1%"] == 1 and summary["below_0.1%"] == 1  # +0.11 %, -0.2 %
    assert abs(summary["mean_gap_percent"] - (0.0 - 0.1 - 0.2 + 0.11) / 4) < 1e-12
    assert not met["worst_case_within_0.1%_no_slower_than_plain"]
    assert not met["median_within_0.1%_in_half_plain_steps"]  # median (45 + 70) / 2 / 100


def test_plain_nudged_spread_counts_gaps_above_a_tenth_of_a_percent_and_slower_runs():
    rows = [_row(100, 60, 40, 0.0), _row(100, 50, 45, 0.0), _row(100, 70, 50, 0.0)]
    for r, (gap, steps) in zip(rows, [(0.002, 90), (-0.01, 130), (0.0004, 100)], strict=True):
        r["plain_nudged"] = {"gap": gap, "ratio_steps": steps / 100}
    spread = summarize(rows)["plain_nudged"]
    assert spread["max_gap_percent"] == 0.2 and spread["min_gap_percent"] == -1.0
    assert spread["above_0.1%"] == 1 and spread["slower"] == 1
    assert spread["below_0.1%"] == 1 and abs(spread["mean_gap_percent"] - (0.2 - 1.0 + 0.04)
                                              / 3) < 1e-12
    assert spread["worst_ratio_steps"] == 1.3


def test_nudged_starts_move_by_the_nudge_and_stay_free():
    domain, starts, _ = scenario(5007, 7)  # box obstacles
    moved = nudged(domain, starts, 5003)
    assert np.allclose(np.hypot(*(moved - starts).T), NUDGE)
    assert all(domain.is_free_point(p) for p in moved)
    assert np.array_equal(moved, nudged(domain, starts, 5003))  # drawn from the seed



def test_a_sweep_with_another_switch_threshold_is_run_with_it_and_kept_beside(capsys):
    import json

    from coverage_ros.bench.planner import main, sweep_part
    from coverage_ros.core.offline.lloyd_solvers import SETTLED

    assert sweep_part("held-out", None) == sweep_part("held-out", SETTLED) == "sweep_held_out"
    assert sweep_part("train", 1e-4) == "sweep_train_settled_0.0001"
    assert sweep_part("held-out", None, "geodesic") == "sweep_held_out_geodesic"
    # a threshold no tail gets below: the accelerated solver never switches, so its descent is
    # plain Lloyd's (its relocations come after)
    assert main(["--no-end-to-end", "--sweep", "train", "--scenarios", "1", "--settled",
                 "1e-300"]) == 0
    sweep = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["sweep"]
    assert sweep["settled"] == 1e-300
    row = sweep["scenarios"][0]
    assert row["accelerated"]["steps_within"] == row["plain"]["steps_within"]
    assert row["accelerated"]["steps"] >= row["plain"]["steps"]
    assert row["accelerated"]["H"] <= row["plain"]["H"]
    assert main(["--no-end-to-end", "--sweep", "train", "--scenarios", "1"]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["sweep"]["scenarios"][0]
    # (the default switches)
    assert row["accelerated"]["steps_within"] < row["plain"]["steps_within"]


def test_a_scenario_takes_another_team_size_and_keeps_its_world():
    domain, starts, about = scenario(5007, 7)
    other, eight, about8 = scenario(5007, 7, robots=8)
    assert about["kind"] == about8["kind"] == "obstacles" and about8["robots"] == 8
    assert len(eight) == 8 and len(starts) == about["robots"] != 8
    assert np.array_equal(domain.free, other.free)
    assert all(other.is_free_point(p) for p in eight)


def test_the_solvers_compare_with_the_geodesic_team_step_when_asked():
    from coverage_ros.bench.lloyd_sweep import RADIUS, TOLERANCE, compare
    from coverage_ros.core.geodesic.domain import CoverageDomain
    from coverage_ros.core.offline.lloyd_team import GeodesicTeam, solve_lloyd
    from coverage_ros.core.world.grid import OCCUPIED, GridMap

    occ = np.zeros((60, 60), dtype=np.int8)
    occ[10:50, 28:32] = OCCUPIED  # (a wall across most of the room: geodesic cells differ)
    domain = CoverageDomain.from_grid(GridMap(occ, 0.05, (0.0, 0.0, 0.0)), RADIUS)
    starts = np.array([[0.3, 0.3], [0.6, 0.3], [0.3, 0.6], [0.6, 0.6]])
    geodesic = compare(domain, starts, team="geodesic")
    own = solve_lloyd(GeodesicTeam(domain), starts, tolerance=TOLERANCE, max_steps=3000)
    assert geodesic["lloyd"]["steps"] == own.steps and geodesic["lloyd"]["H"] == own.cost
    assert geodesic["lloyd"]["H"] != compare(domain, starts)["lloyd"]["H"]
    assert geodesic["accelerated"]["gap"] <= 1e-3
