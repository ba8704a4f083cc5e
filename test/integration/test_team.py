"""The whole stack: coverage-team runs the world and robot nodes as processes over DDS."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from conftest import NO_ESCAPE, WORLDS, entry_point
from rosutil import domain_id
from teamdiag import team_diagnosis

from coverage_ros.cli.plan import main as plan_main

pytestmark = pytest.mark.slow

WORLD = WORLDS / "l_shape.yaml"


def team_cmd(*args: str) -> list[str]:
    """coverage-team with ``args``."""
    return [entry_point("coverage-team"), "--world", str(WORLD), "--quiet",
            "--no-markers", *args]


def best_plan_cost(robots: int, seeds, tmp_path) -> float:
    """The best final H coverage-plan finds on the same map from clustered starts (of 3 and 4
    robots, seeds 0 and 2 end in the same configuration, H within 0.002 %: the team's seed
    serves), with the team's accelerated solver: the robots' own updates end within 0.002 %
    of it here, in 30 times its time (the closet escape prices every move at the end)."""
    best = float("inf")
    for seed in seeds:
        out = tmp_path / f"plan-{robots}-{seed}.json"
        assert plan_main(["--map", str(WORLD), "--robots", str(robots), "--seed", str(seed),
                          "--solver", "accelerated", "--json", str(out), "--quiet"]) == 0
        best = min(best, json.loads(out.read_text())["H"])
    return best


def run_team(tmp_path, *args: str, offset: int) -> dict:
    out = tmp_path / "team"
    proc = subprocess.run(team_cmd("--out", str(out), "--domain-id", str(domain_id(offset)),
                                   *args), capture_output=True, text=True, timeout=1100)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads((out / "summary.json").read_text())


@pytest.mark.lockstep
def test_geodesic_team_spreads_out_and_reaches_the_planned_cost(tmp_path):
    summary = run_team(tmp_path, "--robots", "4", "--duration", "100", "--until-settled", "20",
                       "--seed", "2", "--lockstep", offset=12)
    m = summary["metrics"]
    assert summary["strategy"] == "geodesic" and len(summary["robots"]) == 4
    assert summary["settled_at"] is not None, team_diagnosis(summary, tmp_path / "team")
    assert m["H"] <= 0.6 * m["H_start"], team_diagnosis(summary, tmp_path / "team")
    best = best_plan_cost(4, (2,), tmp_path)
    print(f"H {m['H']:.4f}, best plan {best:.4f} ({m['H'] / best:.4f}x)")
    # The lock-step run: H within 1 % of its end from 45 s of sim time, so it ends settled at
    # 65 s, at 1.0023x the best plan.
    assert m["H"] <= 1.03 * best, (best, team_diagnosis(summary, tmp_path / "team"))
    assert all(r["collisions"] == 0 for r in summary["robots"]), summary["robots"]
    assert m["min_separation"] >= 2 * 0.105
    assert m["coverage_ratio"] > 0.95
    for key in ("world", "seed", "sim_time", "wall_time", "rtf"):
        assert key in summary
    assert all(len(r["start"]) == 3 and len(r["final"]) == 3 and r["path_length"] > 0
               for r in summary["robots"])
    # summary.png: the final cells, and each robot's path ending in a disc of its colour.
    from PIL import Image

    from coverage_ros.viz.colors import robot_color

    img = np.asarray(Image.open(tmp_path / "team" / "summary.png").convert("RGB"))
    assert min(img.shape[:2]) >= 300
    pixels = {tuple(p) for p in img.reshape(-1, 3)}
    for i in range(4):
        assert tuple(int(v) for v in robot_color(i) * 0.7) in pixels, i


@pytest.mark.lockstep
def test_a_lost_robots_area_is_absorbed_by_the_others(tmp_path):
    # Robot 1 killed at 25 s of sim time, at an exact tick: H of the four jumps (649 -> 889 in
    # the run of the seed) and the three survivors bring it down to 1.02x the best plan of
    # three by 50 s, 1.001x by 60 s. (Without the closet escape: the test is of the others
    # spreading into the lost robot's cell, and a settled team's pricing of moves is most of
    # its CPU.)
    summary = run_team(tmp_path, "--robots", "4", "--duration", "60", "--seed", "2",
                       "--kill", "1@25", "--lockstep", *NO_ESCAPE,
                       offset=13)
    robots = {r["id"]: r for r in summary["robots"]}
    assert robots[1]["lost_at"] == pytest.approx(25.0, abs=0.2)
    assert all("lost_at" not in robots[i] for i in (0, 2, 3))
    m = summary["metrics"]  # H of the three survivors at the end
    best = best_plan_cost(3, (2,), tmp_path)
    assert m["H"] <= 1.05 * best, (best, team_diagnosis(summary, tmp_path / "team"))
    assert all(robots[i]["collisions"] == 0 for i in (0, 2, 3))


MIXED_WORLD = """\
name: mixed
bounds: [0, 0, 8, 6]
obstacles:
  - {type: box, center: [4.0, 3.0], size: [0.4, 2.0]}
robots:
  - {pose: [1.0, 1.0, 0.0]}
  - {pose: [1.6, 1.0, 0.0], radius: 0.16, v_max: 0.3, sensor_radius: 2.0, power_weight: 0.2}
  - {pose: [1.0, 1.7, 0.0], radius: 0.13, v_max: 0.15, w_max: 2.0, sensor_radius: 2.5}
"""


@pytest.mark.lockstep
def test_each_robot_runs_with_its_own_spec_from_the_world_file(tmp_path):
    """Robots that differ in radius, speed and sensing: each simulated body and each robot
    node use that robot's own values (the world node's status, the robot's start-up log)."""
    from coverage_ros.core.world import load_world

    world_file = tmp_path / "mixed.yaml"
    world_file.write_text(MIXED_WORLD)
    out = tmp_path / "team"
    proc = subprocess.run(
        [entry_point("coverage-team"), "--world", str(world_file), "--quiet",
         "--robots", "3", "--duration", "8", "--lockstep", "--out", str(out),
         "--domain-id", str(domain_id(14))], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    world = load_world(world_file)
    for r in summary["robots"]:
        want = world.robot_spec(r["id"]).numbers()
        assert r["spec"] == pytest.approx(want), r["id"]
        assert r["body"] == pytest.approx(want), r["id"]  # what the world node simulates
        assert r["start"][:2] == pytest.approx([s for s in (world.starts[r["id"]].x,
                                                            world.starts[r["id"]].y)])
        log = (out / "logs" / f"robot_{r['id']}.log").read_text()
        assert world.robot_spec(r["id"]).describe() in log, log[-2000:]
    assert summary["robots"][1]["spec"]["radius"] == 0.16
    assert summary["robots"][2]["spec"]["v_max"] == 0.15
