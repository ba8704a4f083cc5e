"""coverage-plan: the offline planner's outputs and errors."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from conftest import NO_ESCAPE, REPO, WORLDS, entry_point, shared_map

from coverage_ros.cli.arguments import attach_values
from coverage_ros.cli.plan import main
from coverage_ros.core.world import clearance, load_world, parse_poses
from coverage_ros.errors import ConfigError


@pytest.fixture(scope="module")
def plan(tmp_path_factory):
    out = tmp_path_factory.mktemp("plan")
    # (the outputs of the default strategy; without its closet escape, which test_handover
    # checks and which would take most of the time here)
    code = main(["--map", str(WORLDS / "l_shape.yaml"), "--robots", "3", "--seed", "4",
                 *NO_ESCAPE,
                 "--json", str(out / "p.json"), "--png", str(out / "p.png"),
                 "--record", str(out / "p.rrd"), "--quiet"])
    assert code == 0
    return out


def test_json_summary(plan):
    data = json.loads((plan / "p.json").read_text())
    for key in ("map", "strategy", "robots", "start_positions", "positions", "H", "iterations",
                "converged", "update_ms", "grid"):
        assert key in data, key
    assert data["strategy"] == "geodesic" and data["robots"] == 3
    assert data["converged"] is True
    assert set(data["update_ms"]) == {"median", "p90", "max"}
    assert 0 < data["update_ms"]["median"] <= data["update_ms"]["p90"] <= data["update_ms"]["max"]
    assert data["grid"] == {"width": 202, "height": 202, "resolution": 0.05}
    # The robots spread out of their cluster and lower the coverage cost a lot.
    starts, final = np.array(data["start_positions"]), np.array(data["positions"])
    assert np.ptp(starts, axis=0).max() < 1.0 < np.ptp(final, axis=0).max()
    assert data["H"] < 0.3 * data["H_start"]
    world = load_world(WORLDS / "l_shape.yaml")
    for x, y in final:
        assert clearance(world, x, y) >= 0.105


def test_png_picture(plan):
    from PIL import Image

    img = Image.open(plan / "p.png")
    assert img.size[0] >= 800 and img.size[0] == img.size[1]
    colours = {c for _, c in img.getcolors(1 << 20)}
    assert (40, 40, 40) in colours  # the obstacle


def test_recording_holds_the_expected_entities(plan):
    from rerun.chunk import RrdReader

    store = RrdReader(plan / "p.rrd").store()
    paths = set(store.schema().entity_paths())
    expected = {"/world/map", "/world/cells", "/world/robots", "/metrics/H"}
    expected |= {f"/metrics/mass/robot_{i}" for i in range(3)}
    expected |= {f"/world/trajectories/robot_{i}" for i in range(3)}
    assert expected <= paths, expected - paths


@pytest.mark.parametrize("args, message", [
    (["--map", "/nonexistent/map.yaml", "--robots", "2"], "/nonexistent/map.yaml: file not found"),
    (["--map", "office", "--robots", "2", "--starts", "1,1;x,2"], r"--starts\[1\]"),
    (["--map", "office", "--robots", "2", "--starts", "1,1"],
     "--starts: gives 1 poses for 2 robots"),
    (["--map", "office", "--robots", "1", "--starts", "4.0,1.5"], r"--starts\[0\].*inside"),
    (["--map", "nosuchworld", "--robots", "1"], "no shipped world of that name"),
    (["--map", "office", "--robots", "5000"],
     r"--robots: 5000 robots .* \(expected at most \d+\)"),
    (["--map", "office", "--robots", "2", "--robot-radius", "5"],
     "--robot-radius: office has no free space wide enough"),
    (["--map", "office", "--robots", "2", "--tolerance", "-1"], "--tolerance: must be"),
    (["--map", "office", "--robots", "2", "--max-iterations", "0"], "--max-iterations: must be"),
    (["--map", "office", "--robots", "2", "--duration", "10"], "--duration: needs --explore"),
    (["--map", "office", "--robots", "2", "--starts", " "], "--starts: is empty"),
    (["--map", "office", "--robots", "2", "--explore", "--record", "x.rrd"],
     "--record: not with --explore"),
])
def test_errors_are_one_line_and_named(args, message, capsys):
    assert main(args + ["--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    import re

    assert re.search(message, err), err


def test_outputs_that_cannot_be_written_are_refused_before_the_plan(tmp_path, capsys):
    a_file = tmp_path / "a.json"
    a_file.write_text("{}")
    for option, path, message in (
            ("--json", a_file / "x.json", "a.json is a file, not a directory"),
            ("--json", tmp_path, "is a directory"),
            ("--png", tmp_path / "picture", "needs an image file extension"),
            ("--record", tmp_path, "is a directory")):
        assert main(["--map", "office", "--robots", "2", option, str(path), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and f"{option}: " in err and message in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]  # nothing was written


def test_coordinates_may_begin_with_a_minus_sign(tmp_path):
    """Most map_server maps have a negative origin: ``--starts -2.6,...`` is a value, not an
    unknown option (coverage-plan and coverage-team alike)."""
    from coverage_ros.cli.team.options import parse_config

    out = tmp_path / "plan.json"
    assert main(["--map", str(shared_map("tb3_sandbox")), "--robots", "1", "--starts",
                 "-1.0,-0.5", "--json", str(out), "--quiet", "--max-iterations", "1"]) == 0
    config = parse_config(
        ["--starts", "-2.65,-9.15,0;-1,-1,0", "--region", "-1,-1;1,-1;1,1", "--robots", "2"])
    assert config.starts == "-2.65,-9.15,0;-1,-1,0" and config.regions == ("-1,-1;1,-1;1,1",)
    assert attach_values(["--starts"]) == ["--starts"]  # (argparse says what is missing)


def test_parse_poses():
    assert parse_poses("1,2;3,4,0.5").tolist() == [[1, 2, 0], [3, 4, 0.5]]
    with pytest.raises(ConfigError, match="nan"):
        parse_poses("1,nan")


def test_console_script_runs(tmp_path):
    ros2_run = REPO / "install" / "coverage_ros" / "lib" / "coverage_ros" / "coverage-plan"
    assert ros2_run.exists(), "colcon's ros2 run layout has the console script"
    out = subprocess.run([entry_point("coverage-plan"), "--map", "empty",
                          "--robots", "2", "--json", str(tmp_path / "e.json"), "--quiet"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert json.loads((tmp_path / "e.json").read_text())["converged"]


@pytest.mark.parametrize("strategy, max_ratio", [
    ("tangentbug", 0.5), ("acvt", 0.5),
    ("bvc", 1.0),  # drives to density peaks: under a uniform density a cluster stays put
])
def test_other_strategies_write_the_same_outputs(strategy, max_ratio, tmp_path):
    from coverage_ros.core.geodesic.domain import CoverageDomain
    from coverage_ros.core.geodesic.tessellation import Generator, tessellate

    world_path = WORLDS / "l_shape.yaml"
    code = main(["--map", str(world_path), "--robots", "3", "--strategy", strategy,
                 "--json", str(tmp_path / "p.json"), "--png", str(tmp_path / "p.png"),
                 "--quiet"])
    assert code == 0
    data = json.loads((tmp_path / "p.json").read_text())
    assert data["strategy"] == strategy and data["robots"] == 3
    assert isinstance(data["converged"], bool) and data["iterations"] >= 1
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    world = load_world(world_path)
    domain = CoverageDomain.from_grid(world.grid, world.robot.radius, world.density)
    cells = world.grid.world_to_cell(np.array(data["positions"]))
    assert np.all(world.grid.occupancy[cells[:, 0], cells[:, 1]] == 0)  # ends in free space
    H_start = tessellate(domain, [Generator(np.array(p)) for p in data["start_positions"]]).cost
    assert 0 < data["H"] <= max_ratio * H_start, (data["H"], H_start)


def test_picture_underlays_show_a_density_with_peaks_and_nothing_for_a_uniform_one():
    from coverage_ros.viz.png import density_underlay, padded_tracks

    assert density_underlay(np.where(np.eye(4) > 0, 0.0, 2.0)) is None  # 0 off the free space
    w = density_underlay(np.array([[1.0, 3.0], [0.0, 6.0]]))
    assert w == pytest.approx(np.array([[1 / 6, 0.5], [0.0, 1.0]]))
    tracks = padded_tracks(np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 1.0]]),
                           [[(1.0, 0.0), (2.0, 0.0)], []])
    assert tracks.shape == (3, 2, 2)
    assert tracks[:, 1].tolist() == [[5.0, 5.0]] * 3 and tracks[-1, 0].tolist() == [2.0, 0.0]


@pytest.mark.parametrize("n", [1, 2, 7, 226])
def test_summary_quantiles_are_numpys(n):
    from coverage_ros.cli.plan import _quantile

    ms = np.sort(np.random.default_rng(n).random(n))
    for q in (0.5, 0.9):
        assert _quantile(ms, q) == pytest.approx(np.quantile(ms, q), abs=1e-12)
