"""Mixed teams and people in the loop, without ROS: team files (roles, power weights from the
sensor footprint), the launcher's team, the controller's manual and paused modes, and the
terminal teleop's keys."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REPO, WORLDS, entry_point

from coverage_ros.cli.team.members import build_team
from coverage_ros.cli.team.options import RunConfig, parse_config
from coverage_ros.cli.teleop import KEYS, TeleopCommand, split_keys
from coverage_ros.core.control.controller import ControllerConfig, RobotController
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.world import load_world, parse_team, parse_world
from coverage_ros.core.world.grid import OCCUPIED, GridMap
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.errors import ConfigError, WorldError

TEAMS = REPO / "config" / "teams"
BOX = {"name": "box", "bounds": [0, 0, 8, 6]}


def test_power_weight_from_the_sensor_footprint():
    world = parse_world({**BOX, "robots": [
        {"pose": [1, 1, 0], "sensor_radius": 2.0, "power_weight": "sensor"},
        {"pose": [3, 1, 0], "power_weight": "sensor"},  # the default sensor radius
        {"pose": [5, 1, 0], "power_weight": 0.4, "sensor_radius": 1.0}]})
    assert world.robot_spec(0).power_weight == 2.0
    assert world.robot_spec(1).power_weight == RobotSpec().sensor_radius
    assert world.robot_spec(2).power_weight == 0.4
    with pytest.raises(WorldError, match=r"robots\[0\]\.power_weight: unknown power weight"):
        parse_world({**BOX, "robots": [{"pose": [1, 1, 0], "power_weight": "lidar"}]})


def test_team_roles_are_checked_and_written_back():
    world = parse_world(BOX)
    team = parse_team({"robots": [{"id": 0, "role": "human"}, {"id": 1},
                                  {"id": 2, "sensor_radius": 1.5, "power_weight": "sensor"}]},
                      world)
    assert [m.role for m in team] == ["human", "auto", "auto"]
    assert team[2].spec.power_weight == 1.5
    with pytest.raises(WorldError, match=r"robots\[1\]\.role: unknown role"):
        parse_team({"robots": [{"id": 0}, {"id": 1, "role": "pilot"}]}, world)


@pytest.mark.parametrize("name", ["burgers_and_waffles", "sensor_footprints", "one_human"])
def test_shipped_teams_load_on_the_office(name):
    config = parse_config(["--team", str(TEAMS / f"{name}.yaml")])
    team = build_team(load_world(WORLDS / "office.yaml"), config)
    assert [m.id for m in team] == [0, 1, 2, 3]
    assert all(m.start is not None for m in team)  # placed: a seeded cluster
    if name == "burgers_and_waffles":
        assert {m.spec.radius for m in team} == {0.105, 0.22}
        assert {m.spec.v_max for m in team} == {0.22, 0.26}
    if name == "sensor_footprints":
        assert [m.spec.power_weight for m in team] == [2.0, 2.0, 1.0, 1.0]
    if name == "one_human":
        assert [m.role for m in team] == ["human", "auto", "auto", "auto"]


def _args(*argv: str) -> RunConfig:
    return parse_config(list(argv))


def test_the_launchers_team_from_options(tmp_path):
    world = load_world(WORLDS / "office.yaml")
    team = build_team(world, _args("--robots", "3", "--human", "1", "--sensor-radius", "2"))
    assert [m.role for m in team] == ["auto", "human", "auto"]
    assert all(m.spec.sensor_radius == 2.0 for m in team)
    f = tmp_path / "t.yaml"
    f.write_text("robots:\n  - {id: 1, start: [1, 2.5, 0]}\n  - {id: 0, start: [3, 2.5, 0]}\n")
    team = build_team(world, _args("--team", str(f)))
    assert [m.id for m in team] == [0, 1] and team[0].start == (3.0, 2.5, 0.0)
    for argv, message in [
            (["--team", str(f), "--robots", "3"], "--robots: differs from the 2 robots"),
            (["--robots", "2", "--human", "2"], "--human: robot id out of range"),
    ]:
        with pytest.raises(ConfigError, match=message):
            build_team(world, _args(*argv))
    f.write_text("robots:\n  - {id: 0, start: [1, 2.5, 0]}\n  - {id: 2}\n")
    with pytest.raises(ConfigError, match=r"ids must be 0\.\.N-1"):
        build_team(world, _args("--team", str(f)))
    f.write_text("robots:\n  - {id: 0, start: [1, 2.5, 0]}\n  - {id: 1}\n")
    with pytest.raises(ConfigError, match="give every robot a start or none"):
        build_team(world, _args("--team", str(f)))


# ---------------------------------------------------------------------------- controller modes
def corridor() -> CoverageDomain:
    """6 m x 2 m, walled."""
    occ = np.zeros((40, 120), np.int8)
    occ[0, :] = occ[-1, :] = OCCUPIED
    occ[:, 0] = occ[:, -1] = OCCUPIED
    return CoverageDomain.from_grid(GridMap(occ, 0.05), 0.105)


def controller(**over) -> RobotController:
    c = RobotController(corridor(), ControllerConfig(robot_id=0, **over))
    c.set_pose((1.0, 1.0, 0.0))
    return c


def test_a_manual_robot_follows_its_person_within_its_limits():
    c = controller()
    c.update(0.0)
    c.set_manual(True)
    c.teleop(0.1, 0.5, now=1.0)
    assert c.command(1.1, 0.1) == pytest.approx((0.1, 0.5))
    c.teleop(5.0, -9.0, now=1.2)  # beyond the limits: clipped
    assert c.command(1.3, 0.1) == pytest.approx((0.22, -2.84))
    assert c.command(1.2 + 0.6, 0.1) == (0.0, 0.0)  # silent for longer than the timeout
    c.teleop(0.1, 0.0, now=3.0)
    assert c.command(2.0, 0.1) == (0.0, 0.0)  # a command from the future (clock went back)
    result = c.update(2.0)  # the strategy keeps computing the cell ...
    assert result.state["manual"] == 1.0 and result.decision.cell is not None


def test_the_safety_filter_still_stops_a_manual_robot_at_a_wall():
    """A person holds 'full speed ahead' towards the east wall (x = 5.95 m): the robot stops
    short of it."""
    c = controller()
    c.set_pose((5.0, 1.0, 0.0))
    c.set_manual(True)
    pose, dt = np.array([5.0, 1.0, 0.0]), 0.1
    for k in range(60):
        c.teleop(0.22, 0.0, now=k * dt)
        v, w = c.command(k * dt + 0.01, dt)
        pose = pose + [v * dt * np.cos(pose[2]), v * dt * np.sin(pose[2]), w * dt]
        c.set_pose(tuple(pose))
        assert pose[0] + 0.105 < 5.95, k
    assert v == 0.0 and c.safety_note
    assert pose[0] > 5.5  # it did drive up to the wall


def test_pause_holds_and_back_to_autonomous_replans():
    c = controller()
    c.neighbours.receive(1, {"x": 5.0, "y": 1.0}, now=0.0)
    c.update(0.5)
    assert c.path is not None
    c.set_paused(True)
    assert c.command(0.6, 0.1) == (0.0, 0.0)
    c.set_paused(False)
    c.set_manual(True)
    c.set_manual(False)  # the old path started elsewhere: dropped, replanned next update
    assert c.path is None and c.goal is None
    c.update(1.0)
    assert c.path is not None and c.update(1.5).state["manual"] == 0.0


# ---------------------------------------------------------------------------- terminal teleop
def test_teleop_keys_step_the_command_within_the_limits():
    keys = split_keys("\x1b[A\x1b[Aw\x1b[Dzq")
    assert keys == ["\x1b[A", "\x1b[A", "w", "\x1b[D", "q"]  # 'z' is no key
    cmd = TeleopCommand(v_max=0.3, w_max=2.0)
    for k in keys[:-1]:
        cmd.press(KEYS[k])
    assert (cmd.v, cmd.w) == pytest.approx((0.18, 0.4))
    for _ in range(10):
        cmd.press("faster")
        cmd.press("right")
    assert (cmd.v, cmd.w) == (0.3, -2.0)
    cmd.press("stop")
    assert (cmd.v, cmd.w) == (0.0, 0.0)


# ---------------------------------------------------------------------------- travel metric
CORRIDOR = {"name": "corridor", "bounds": [0, 0, 8, 1], "resolution": 0.05,
            "metric": {"regions": [{"type": "box", "center": [6, 0.5], "size": [4, 2],
                                    "zeta": 4.0}]}}


def test_a_world_metric_shifts_the_geodesic_cells():
    """zeta = 4 on x > 4 m: a metre there costs 2. Generators at x = 2 and x = 6 meet where
    x - 2 = 2 (6 - x) ... on the slow side: 2 + 2 (x - 4) = 2 (6 - x), x = 4.5 m (3.5 m of
    free corridor to the fast robot's right instead of the Euclidean bisector at 4 m)."""
    from coverage_ros.core.geodesic.tessellation import Generator, tessellate
    from coverage_ros.core.world.metric import zeta_on_grid

    world = parse_world(CORRIDOR)
    domain = world_domain(world, 0.0)
    assert domain.zeta is not None and domain.zeta.max() == 4.0 and domain.zeta.min() == 1.0
    gens = [Generator(np.array([2.0, 0.5]), 0.0), Generator(np.array([6.0, 0.5]), 0.0)]
    cells = tessellate(domain, gens)
    row = cells.labels[domain.shape[0] // 2]
    xs = domain.to_map(np.stack([np.arange(len(row)) + 0.5,
                                 np.full(len(row), domain.shape[0] // 2 + 0.5)], axis=1))[:, 0]
    boundary = xs[row == 0].max()
    assert boundary == pytest.approx(4.5, abs=0.1)
    plain = tessellate(CoverageDomain.from_grid(world.grid, 0.0), gens)
    assert xs[plain.labels[domain.shape[0] // 2] == 0].max() == pytest.approx(4.0, abs=0.1)
    # A robot node builds the same zeta on whatever lattice its map comes on.
    coarse = GridMap(np.zeros((5, 40), np.int8), 0.2)
    z = zeta_on_grid(world.metric, coarse)
    assert z.shape == (5, 40) and z[:, :20].max() == 1.0 and z[:, 21:].min() == 4.0
    assert zeta_on_grid(parse_world(BOX).metric, coarse) is None


@pytest.mark.parametrize(("metric", "message"), [
    ({"zeta": 0}, r"metric\.zeta: must be > 0"),
    ({"regions": [{"type": "box", "center": [1, 1], "size": [1, 1]}]}, "with a 'zeta'"),
    ({"regions": [{"type": "blob", "zeta": 2}]}, r"regions\[0\]\.type: unknown obstacle type"),
    ({"speed": 2}, r"metric: speed: unknown key|metric\.speed"),
])
def test_bad_metrics_are_named(metric, message):
    with pytest.raises(WorldError, match=message):
        parse_world({**BOX, "metric": metric})


@pytest.mark.slow
def test_impossible_teams_are_refused_before_anything_starts(tmp_path):
    import subprocess

    out = tmp_path / "team"
    bad = tmp_path / "bad.yaml"
    bad.write_text("robots:\n  - {id: 0, role: pilot}\n")
    for args, message in (
            (["--map-free"], "--map-free: strategy geodesic needs a map"),
            (["--strategy", "bvc", "--map-free", "--explore"], "unknown strategy for exploring"),
            (["--human", "7"], "--human: robot id out of range 0..3"),
            (["--team", str(bad)], "robots[0].role: unknown role"),
            (["--team", str(TEAMS / "one_human.yaml"), "--robots", "5"], "--robots: differs")):
        proc = subprocess.run([entry_point("coverage-team"), "--world", "office",
                               "--out", str(out), *args], capture_output=True, text=True,
                              timeout=180)
        assert proc.returncode == 2 and message in proc.stderr, (args, proc.stderr)
        assert not (out / "logs").exists()  # nothing was started


@pytest.mark.parametrize("chart", [{"type": "sphere", "cells_per_pi": 32},
                                   {"type": "torus", "cells": 48, "R": 2.0, "r": 1.0}])
def test_a_chart_world_is_planned_on_its_surface_and_refused_by_the_team(tmp_path, chart):
    """A world file may be a curved surface through a chart (Sec. 4.1): coverage-plan runs on
    the chart's metric (positions are chart coordinates); nothing that simulates or drives
    robots takes it."""
    import json

    import yaml

    from coverage_ros.cli.plan import main as plan_main
    from coverage_ros.core.world import load_planar_world, load_world

    path = tmp_path / "surface.yaml"
    path.write_text(yaml.safe_dump({"name": "surface", "chart": chart, "density": {
        "type": "gaussian_mixture", "components": [{"mean": [1.2, 3.0], "sigma": 0.4}]}}))
    world = load_world(path)
    domain = world_domain(world, 0.105)
    assert domain.tensor is not None and domain.shape == world.grid.shape
    out = tmp_path / "plan.json"
    assert plan_main(["--map", str(path), "--robots", "4", "--json", str(out), "--quiet"]) == 0
    result = json.loads(out.read_text())
    assert result["converged"] and result["H"] < 0.2 * result["H_start"], result
    with pytest.raises(WorldError, match=f"is a {chart['type']} chart"):
        load_planar_world(path)


@pytest.mark.parametrize(("data", "message"), [
    ({"chart": {"type": "cone"}}, r"chart: must be a mapping with a 'type'"),
    ({"chart": {"type": "sphere", "cells_per_pi": 4}}, r"cells_per_pi: must be an integer"),
    ({"chart": {"type": "torus", "R": 1.0, "r": 2.0}}, r"chart\.R: must exceed r"),
    ({"chart": {"type": "sphere"}, "bounds": [0, 0, 1, 1]}, r"bounds: does not go with"),
])
def test_bad_charts_are_named(data, message):
    with pytest.raises(WorldError, match=message):
        parse_world(data)
