"""One robot spec from the world file to the robot: world entries, team files, robot_node
parameter overrides, and the strategy settings built once at the boundary."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import yaml

from coverage_ros.core.strategies import (
    STRATEGIES,
    StrategyChoice,
    StrategyContext,
    make_strategy,
    strategy_choice,
)
from coverage_ros.core.world import load_team, parse_team, parse_world, write_team
from coverage_ros.core.world.placement import team_starts
from coverage_ros.core.world.robot import TB3_RADIUS, TB3_V_MAX, RobotSpec
from coverage_ros.errors import ConfigError, WorldError
from coverage_ros.nodes.robot_config import load_robot_inputs
from coverage_ros.nodes.robot_parameters import PARAMETERS

MIXED = {
    "name": "mixed", "bounds": [0, 0, 8, 6],
    "robot": {"sensor_radius": 3.0},
    "robots": [
        {"pose": [1.0, 1.0, 0.0]},
        {"pose": [2.0, 1.0, 0.0], "radius": 0.16, "v_max": 0.26, "sensor_radius": 2.0},
        {"pose": [3.0, 1.0, 0.0], "power_weight": 0.3, "lidar": {"range_max": 8.0}},
    ],
}


def _values(**over) -> dict:
    values = {name: default for name, (default, _) in PARAMETERS.items()}
    values.update(over)
    return values


def test_world_entries_give_each_robot_its_own_spec():
    world = parse_world(MIXED)
    a, b, c = (world.robot_spec(i) for i in range(3))
    assert (a.radius, a.v_max, a.sensor_radius) == (TB3_RADIUS, TB3_V_MAX, 3.0)
    assert (b.radius, b.v_max, b.sensor_radius) == (0.16, 0.26, 2.0)
    assert c.power_weight == 0.3 and c.lidar.range_max == 8.0 and c.sensor_radius == 3.0
    assert world.robot_spec(7) == world.robot  # beyond the entries: the world's robot


@pytest.mark.parametrize(("entry", "message"), [
    ({"pose": [1, 1, 0], "radius": -0.1}, r"robots\[0\]\.radius: must be > 0"),
    ({"pose": [1, 1, 0], "power_weight": -1}, r"robots\[0\]\.power_weight: must be >= 0"),
    ({"pose": [1, 1, 0], "sensor_radius": "far"}, r"robots\[0\]\.sensor_radius"),
    ({"pose": [1, 1, 0], "wheels": 3}, r"robots\[0\]\.wheels: unknown key"),
])
def test_bad_robot_entries_are_named(entry, message):
    with pytest.raises(WorldError, match=message):
        parse_world({"bounds": [0, 0, 5, 5], "robots": [entry]})


def test_team_file_round_trip_keeps_every_field(tmp_path):
    world = parse_world(MIXED)
    team = parse_team({"robots": [
        {"id": 0, "start": [1.0, 1.0, 0.5]},
        {"id": 1, "start": [2.0, 1.0], "v_max": 0.3},
        {"id": 2},
    ]}, world)
    assert team[0].spec == world.robot_spec(0) and team[0].start == (1.0, 1.0, 0.5)
    assert team[1].spec == replace(world.robot_spec(1), v_max=0.3)  # world entry, then the key
    assert team[1].start == (2.0, 1.0, 0.0) and team[2].start is None
    write_team(tmp_path / "team.yaml", team)
    again = load_team(tmp_path / "team.yaml", world)
    assert again == team
    written = yaml.safe_load((tmp_path / "team.yaml").read_text())["robots"][1]
    assert written["radius"] == 0.16 and written["sensor_radius"] == 2.0


@pytest.mark.parametrize(("data", "message"), [
    ({"robots": []}, "non-empty list"),
    ({"robots": [{"start": [1, 1]}]}, r"robots\[0\]: must be a mapping with an 'id'"),
    ({"robots": [{"id": 0}, {"id": 0}]}, r"robots\[1\]\.id: is used twice"),
    ({"robots": [{"id": 0, "start": [1, 1]}, {"id": 1, "start": [1.1, 1]}]}, "overlaps"),
    ({"robots": [{"id": 0, "start": [0.05, 1]}]}, "inside an obstacle or wall"),
    ({"robots": [{"id": 0, "radius": 0}]}, r"robots\[0\]\.radius: must be > 0"),
    ({"team": []}, "team: team: unknown key"),
])
def test_bad_team_files_are_refused_with_the_field(data, message):
    with pytest.raises(WorldError, match=message):
        parse_team(data, parse_world(MIXED), "team")


def test_team_starts_use_the_world_poses_then_a_cluster():
    world = parse_world(MIXED)
    specs = [world.robot_spec(i) for i in range(3)]
    np.testing.assert_allclose(team_starts(world, specs, None, 0)[:, :2],
                               [[1, 1], [2, 1], [3, 1]])
    four = [world.robot_spec(i) for i in range(4)]  # more robots than poses: a cluster
    cluster = team_starts(world, four, None, 0)
    assert len(cluster) == 4 and not np.allclose(cluster[:3, :2], [[1, 1], [2, 1], [3, 1]])
    with pytest.raises(ConfigError, match="gives 1 poses for 3 robots"):
        team_starts(world, specs, "1,1", 0)


def test_robot_node_spec_comes_from_the_world_entry_and_parameters_override_it(tmp_path):
    path = tmp_path / "mixed.yaml"
    path.write_text(yaml.safe_dump(MIXED))
    plain = load_robot_inputs(_values(world=str(path), robot_id=1), "/robot_1")
    assert plain.config.controller.robot == parse_world(MIXED).robot_spec(1)
    over = load_robot_inputs(_values(world=str(path), robot_id=1, v_max=0.4,
                                     power_weight=0.0), "/robot_1")
    spec = over.config.controller.robot
    assert (spec.radius, spec.v_max, spec.sensor_radius, spec.power_weight) == \
        (0.16, 0.4, 2.0, 0.0)
    # No world: TurtleBot3 defaults; the id from the namespace.
    bare = load_robot_inputs(_values(), "/robot_4")
    assert bare.config.controller.robot == RobotSpec() and bare.config.controller.robot_id == 4


@pytest.mark.parametrize(("over", "message"), [
    ({"robot_radius": 0.0}, "parameter radius: must be > 0"),
    ({"v_max": float("inf")}, "v_max: must be a finite number"),
    ({"strategy": "magic"}, "strategy: unknown strategy"),
    ({"strategy_params": "{method: nope}"}, "method: unknown method"),
    ({"strategy_params": "[1, 2]"}, "strategy_params: must be a YAML mapping"),
])
def test_robot_node_configuration_errors_name_the_parameter(over, message):
    with pytest.raises(ConfigError, match=message):
        load_robot_inputs(_values(**over), "/robot_0")


def test_strategy_settings_are_typed_and_validated_once():
    assert set(STRATEGIES) == {"geodesic", "lloyd", "tangentbug", "bvc", "acvt"}
    choice = strategy_choice("bvc", {"gamma": 4, "guided": False})
    assert isinstance(choice, StrategyChoice) and choice.params.gamma == 4
    assert choice.needs_scan and not strategy_choice("lloyd").needs_scan
    with pytest.raises(ConfigError, match=r"bvc\.guided: must be true or false"):
        strategy_choice("bvc", {"guided": "yes"})
    with pytest.raises(ConfigError, match="lloyd: unknown parameters"):
        strategy_choice("lloyd", {"gamma": 1.0})
    with pytest.raises(ConfigError, match="settings of the wrong kind"):
        StrategyChoice("geodesic", choice.params)


def test_a_node_imports_only_the_strategies_it_runs():
    """The registry imports a strategy when it is first asked for: the world node imports
    none, and a registered class is the one of that name."""
    import subprocess
    import sys

    code = ("import sys, coverage_ros.nodes.world_node as w; "
            "from coverage_ros.core.strategies import STRATEGIES, EXPLORERS; "
            "before = sorted(m for m in sys.modules if m.endswith('.strategy')); "
            "names = [STRATEGIES[n].name for n in STRATEGIES] + [EXPLORERS[n].name "
            "for n in EXPLORERS]; print(before, names)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=180).stdout.strip()
    assert out == ("[] ['acvt', 'bvc', 'geodesic', 'lloyd', 'tangentbug', 'geodesic', "
                   "'frontier']"), out


def test_every_strategy_reads_its_robot_from_the_spec():
    """A strategy sees the robot's own sensor radius and power weight, not defaults."""
    from coverage_ros.core.geodesic.domain import CoverageDomain
    from coverage_ros.core.strategies import Observation

    world = parse_world({"bounds": [0, 0, 6, 6]})
    domain = CoverageDomain.from_grid(world.grid, TB3_RADIUS)
    spec = RobotSpec(sensor_radius=2.0, power_weight=0.25, v_max=0.3)
    for name in STRATEGIES:
        robot = make_strategy(name, StrategyContext(domain=domain, robot=spec))
        shared = robot.shared_state(Observation(0, np.array([3.0, 3.0, 0.0]), 0.0))
        assert shared.weight == 0.25, name
    bvc = make_strategy("bvc", StrategyContext(domain=domain, robot=spec))
    assert bvc.sensor_radius == 2.0 and bvc.u_max == 0.3
