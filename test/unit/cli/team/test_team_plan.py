"""coverage-team's plan and summary, without ROS: what a configuration starts (plan.py) and what
a run log gives (summary.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from coverage_ros.cli.team.options import parse_config
from coverage_ros.cli.team.plan import plan_run
from coverage_ros.cli.team.robots import CONTAINER_SEARCH_REUSE
from coverage_ros.cli.team.summary import (
    WALL_CLOCK_KEYS,
    RunLog,
    deterministic_part,
    summarize,
    summary_table,
    team_cost,
)
from coverage_ros.core.geodesic.tessellation import Generator, fast_tessellate
from coverage_ros.errors import ConfigError


def _plan(tmp_path, *argv: str):
    return plan_run(parse_config(["--world", "office", "--quiet", *argv]), tmp_path / "run",
                    env={"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, cores=2)


def test_a_plan_starts_nothing_and_writes_nothing(tmp_path):
    plan = _plan(tmp_path, "--robots", "3", "--lockstep", "--kill", "1@5")
    assert not (tmp_path / "run").exists()
    assert plan.robots == 3 and [f.robot for f in plan.faults] == [1]
    assert [p.name for p in plan.processes] == ["robot_0", "robot_1", "robot_2"]
    world = " ".join(plan.world_command())
    assert "lockstep:=true" in world and "real_time_factor:=0.0" in world
    assert str((tmp_path / "run" / "team.yaml").resolve()) in world
    assert "lockstep_timeout" not in world  # (the world's own: a silent member is dropped)
    env = plan.environment({"PATH": "/bin"}, 17)
    assert env["ROS_DOMAIN_ID"] == "17" and env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert env["PATH"] == "/bin"


def test_the_world_waits_for_a_restarted_robot_as_for_one_starting_up(tmp_path):
    plan = _plan(tmp_path, "--robots", "3", "--lockstep", "--restart", "1@5")
    assert f"lockstep_timeout:={plan.startup_timeout}" in " ".join(plan.world_command())


def test_robots_sharing_a_process_reuse_searches_unless_told_otherwise(tmp_path):
    plan = _plan(tmp_path, "--robots", "4", "--robots-per-process", "2")
    (group, *_) = plan.processes
    assert group.ids == (0, 2) and group.params_file is not None
    params = yaml.safe_load(group.params_text)["/robot_0/coverage_robot"]["ros__parameters"]
    assert params["search_reuse"] == CONTAINER_SEARCH_REUSE and params["team_size"] == 4
    plan = _plan(tmp_path, "--robots", "4", "--robots-per-process", "2",
                 "--robot-param", "search_reuse:=0.0")
    params = yaml.safe_load(plan.processes[0].params_text)["/robot_0/coverage_robot"]
    assert params["ros__parameters"]["search_reuse"] == 0.0
    alone = _plan(tmp_path, "--robots", "2")
    assert all("search_reuse" not in " ".join(p.cmd) for p in alone.processes)


@pytest.mark.parametrize("argv, message", [
    (["--robots", "2", "--kill", "2@3"], "--kill: robot id out of range 0..1"),
    (["--robots", "2", "--remote-robots", "1", "--kill", "1@3"], "cannot reach a robot"),
    (["--robots", "2", "--region", "100,100;101,100;101,101"], "--region: holds no free space"),
])
def test_impossible_plans_are_refused_with_the_option_to_change(tmp_path, argv, message):
    with pytest.raises(ConfigError, match=message):
        _plan(tmp_path, *argv)


def test_the_summary_scores_the_robots_present(tmp_path):
    plan = _plan(tmp_path, "--robots", "3")
    team = plan.team
    starts = np.array([m.start for m in team])
    log = RunLog(sim_time=42.0, ready_at=2.0, sim_start=2.0, wall_start=0.0,
                 run_span=(40.0, 10.0))
    moved = starts.copy()
    moved[0, :2] += [0.5, 0.0]
    for i in range(3):
        log.poses[i] = moved[i]
        log.status[i] = {"x": moved[i, 0], "y": moved[i, 1], "yaw": 0.0, "path_length": 0.5 * i,
                         "collisions": 0, "min_separation": 0.4 + i}
    log.lost[2] = 30.0
    log.poses.pop(2)
    log.restarted[1] = [12.5]
    # H of robots 0 and 1 where they are; H_start of all three where they started.
    expected = fast_tessellate(plan.domain, [Generator(moved[i, :2], 0.0) for i in (0, 1)])
    H = float(expected.cost)
    log.H_samples = [(2.0, 2 * H), (22.0, 1.01 * H), (42.0, H)]
    typed = summarize(log, team, plan.world, plan.domain, "geodesic", 7, 11.0, False)
    assert typed.robots[2].lost_at == 30.0 and typed.metrics.H is not None
    summary = typed.as_dict()
    m = summary["metrics"]
    assert m["H"] == pytest.approx(float(expected.cost))
    assert m["H"] == pytest.approx(team_cost(plan.domain, team, log))
    start = fast_tessellate(plan.domain, [Generator(s[:2], 0.0) for s in starts])
    assert m["H_start"] == pytest.approx(float(start.cost))
    assert m["min_separation"] == 0.4 and m["converged_at"] == 20.0
    assert [t for t, _ in m["H_series"]] == [0.0, 20.0, 40.0]
    robots = summary["robots"]
    assert robots[2]["lost_at"] == 30.0 and robots[1]["restarted_at"] == [12.5]
    assert "lost_at" not in robots[0] and "restarted_at" not in robots[0]
    assert list(summary) == ["world", "strategy", "seed", "sim_time", "wall_time", "rtf",
                             "ready_at", "interrupted", "robots", "metrics", "region"]
    assert robots[1]["path_length"] == 0.5 and robots[0]["final"][0] == pytest.approx(
        moved[0, 0])
    assert summary["rtf"] == 4.0 and summary["seed"] == 7 and summary["ready_at"] == 2.0
    assert set(summary) - set(deterministic_part(summary)) == {"wall_time", "rtf"}
    assert "% lower), " in summary_table(summary)
    summary["metrics"]["H"] = 1.31 * summary["metrics"]["H_start"]
    assert "31 % higher), " in summary_table(summary)
    assert set(WALL_CLOCK_KEYS) >= {"wall_time", "rtf"}


def test_a_summary_of_a_team_that_never_came_up():
    from coverage_ros.core.geodesic.world_domain import world_domain
    from coverage_ros.core.world import TeamMember, load_planar_world
    from coverage_ros.worlds import resolve_world_path

    world = load_planar_world(resolve_world_path("office"))
    team = (TeamMember(0, (2.0, 2.5, 0.0), world.robot_spec(0)),)
    summary = summarize(RunLog(), team, world, world_domain(world, 0.105), "lloyd", 0, 1.0,
                        True).as_dict()
    assert summary["interrupted"] and summary["metrics"]["H"] is None
    assert summary["metrics"]["converged_at"] is None and summary["rtf"] == 0.0
    assert math.isfinite(summary["metrics"]["H_start"])


def test_converged_at_needs_h_settled_before_the_end():
    from coverage_ros.cli.team.summary import converged_at

    settled = [(0.0, 100.0), (5.0, 50.0), (10.0, 40.5), (15.0, 40.1), (20.0, 40.0)]
    assert converged_at(settled, 40.0, None) == 10.0
    assert converged_at(settled, 40.0, 2.0) == 8.0
    moving = [(0.0, 100.0), (5.0, 50.0), (10.0, 89.4), (15.0, 103.7), (20.0, 135.2)]
    assert converged_at(moving, 135.2, None) is None  # (only the last sample: still moving)


def test_an_earlier_runs_outputs_are_cleared_and_nothing_else(tmp_path):
    from coverage_ros.cli.team.launch import clear_previous_run

    (tmp_path / "logs").mkdir()
    for name in ("team.yaml", "summary.json", "explored_map.pgm", "logs/robot_3.log",
                 "notes.txt"):
        (tmp_path / name).write_text("x")
    assert clear_previous_run(tmp_path)
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["logs", "notes.txt"]
    assert not clear_previous_run(tmp_path)


def test_an_interrupted_runs_series_ends_with_its_final_h(tmp_path):
    plan = _plan(tmp_path, "--robots", "2")
    starts = np.array([m.start for m in plan.team])
    log = RunLog(sim_time=37.6, ready_at=2.0, sim_start=2.0, wall_start=0.0)
    for i in range(2):
        log.poses[i] = starts[i]
        log.status[i] = {"x": starts[i, 0], "y": starts[i, 1], "yaw": 0.0}
    log.H_samples = [(2.0, 500.0), (35.0, 400.0)]  # (the interrupt came before the next one)
    m = summarize(log, plan.team, plan.world, plan.domain, "geodesic", 0, 5.0,
                  True).as_dict()["metrics"]
    assert m["H_series"][:2] == [[0.0, 500.0], [33.0, 400.0]]
    assert m["H_series"][-1] == [35.6, pytest.approx(m["H"], abs=1e-6)]
