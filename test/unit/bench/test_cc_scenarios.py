"""scripts/bench_planner's random scenarios of CoverageControl's kind: what they hold and how a
sweep's rows are judged."""

from __future__ import annotations

import numpy as np
import pytest

from coverage_ros.bench.cc_scenarios import SIDE, SPACING, TEAMS, draw, summarize, targets
from coverage_ros.bench.cc_scenarios import row as scenario_row
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.world.loading import parse_world


def test_a_scenario_is_drawn_from_its_seed_alone_and_is_a_valid_world():
    a, robots, cells = draw(7003, 3)
    assert draw(7003, 3) == (a, robots, cells)
    assert draw(7004, 3)[0] != a
    assert robots == TEAMS[3 % len(TEAMS)] and len(a["robots"]) == robots
    assert 1 <= len(a["density"]["components"]) <= 5
    world = parse_world(a, source="drawn")  # (refuses starts in a wall or on each other)
    assert len(world.starts) == robots
    domain = world_domain(world, world.robot_spec(0).radius)
    assert domain.shape == (cells, cells)
    P = np.array([[s.x, s.y] for s in world.starts])
    gaps = np.hypot(*(P[:, None, :] - P[None, :, :]).transpose(2, 0, 1))
    assert gaps[~np.eye(robots, dtype=bool)].min() >= SPACING
    # one corner: the cluster fits in a quarter of the square
    assert np.ptp(P, axis=0).max() < SIDE / 2


def test_every_team_size_meets_both_grids_within_nine_scenarios():
    pairs = {draw(7000 + i, i)[1:] for i in range(9)}
    assert pairs == {(n, c) for n in TEAMS for c in (402, 1024)}


def _result(steps, wall_s, step_ms, cc_step_ms, cc_wall_s=None):
    out = {"coverage_plan": {"steps": steps, "end_to_end_ms_per_step": wall_s * 1e3 / steps,
                             "step_ms": step_ms, "wall_s": wall_s},
           "coveragecontrol": {"steps": steps, "step_ms": cc_step_ms},
           "ratio_end_to_end_over": {"step": wall_s * 1e3 / steps / cc_step_ms}}
    if cc_wall_s is not None:
        out["coveragecontrol"]["end_to_end_ms_per_step"] = cc_wall_s * 1e3 / steps
        out["ratio_end_to_end_over"]["end_to_end"] = wall_s / cc_wall_s
    return out


def test_rows_give_the_fixed_cost_and_the_steps_a_run_needs_to_meet_the_target():
    world = {"density": {"components": [{}, {}]}}
    # 100 steps of 0.5 ms in 0.2 s: 150 ms beside the steps; 1.5 ms / step is gained against
    # a 2 ms step, so 100 steps are the break-even
    row = scenario_row(1, 402, world, 8, _result(100, 0.2, 0.5, 2.0))
    assert row["fixed_ms"] == pytest.approx(150.0)
    assert row["break_even_steps"] == 100 and row["met"] and row["gaussians"] == 2
    short = scenario_row(2, 402, world, 8, _result(50, 0.175, 0.5, 2.0))
    assert not short["met"] and short["ratio"] == pytest.approx(1.75)
    slower = scenario_row(3, 402, world, 8, _result(100, 0.3, 2.5, 2.0))
    assert slower["break_even_steps"] is None  # (a step slower than theirs never breaks even)
    summary = summarize([row, short, slower])
    assert summary["met"] == 1 and summary["compared"] == 3
    assert summary["worst_ratio"] == pytest.approx(1.75)
    assert summary["fewest_steps_met"] == 100 and summary["most_steps_not_met"] == 100
    (target,) = targets(summary)
    assert not target["met"] and target["value"].startswith("1 of 3")
    assert targets(summarize([row]))[0]["met"]


def test_without_coveragecontrol_rows_keep_our_figures_and_nothing_is_judged():
    result = _result(100, 0.2, 0.5, 2.0)
    result["coveragecontrol"] = {"not_installed": "no network"}
    row = scenario_row(1, 402, {"density": {"components": [{}]}}, 8, result)
    assert "ratio" not in row and "met" not in row
    assert summarize([row]) == {"scenarios": 1, "compared": 0}
    assert targets(summarize([row])) == []


def test_rows_set_the_two_processes_side_by_side_when_both_were_timed():
    world = {"density": {"components": [{}]}}
    # 50 steps: ours 0.175 s against their step of 2 ms (not met), but their process took 0.35 s
    short = scenario_row(1, 402, world, 8, _result(50, 0.175, 0.5, 2.0, cc_wall_s=0.35))
    assert not short["met"] and short["ratio_end_to_end"] == pytest.approx(0.5)
    assert short["cc_end_to_end_ms_per_step"] == pytest.approx(7.0)
    slow = scenario_row(2, 402, world, 8, _result(100, 0.3, 2.5, 2.0, cc_wall_s=0.25))
    summary = summarize([short, slow])
    assert summary["met_end_to_end"] == 1 and summary["worst_ratio_end_to_end"] == 1.2
    step, whole = targets(summary)
    assert not step["met"] and not whole["met"] and whole["value"].startswith("1 of 2")
    assert targets(summarize([short]))[1]["met"]
    # (a row without their process's time: the summary judges only the step)
    assert "met_end_to_end" not in summarize([short, scenario_row(3, 402, world, 8,
                                                                  _result(100, 0.2, 0.5, 2.0))])
