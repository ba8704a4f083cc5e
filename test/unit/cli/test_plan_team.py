"""coverage-plan with the team solvers: the summary's H is the geodesic tessellation's score on
every map (from the team's own step where the free space is a rectangle), and the Euclidean
team's run imports no scipy (its import is most of a short plan's time)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO

from coverage_ros.cli.plan import main
from coverage_ros.core.geodesic.tessellation import Generator, tessellate
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.lloyd_team import EuclideanTeam
from coverage_ros.core.world import load_world
from coverage_ros.worlds import resolve_world_path


@pytest.mark.parametrize("world, rectangle", [("gaussians", True), ("field", False)])
def test_summary_scores_are_the_geodesic_tessellations(tmp_path, world, rectangle):
    out = tmp_path / "plan.json"
    assert main(["--map", world, "--robots", "5", "--strategy", "lloyd", "--solver", "lloyd",
                 "--max-iterations", "15", "--json", str(out), "--quiet"]) == 0
    data = json.loads(out.read_text())
    domain = world_domain(load_world(resolve_world_path(world)), 0.105)
    assert EuclideanTeam(domain).is_geodesic is rectangle
    for key, where in (("H", "positions"), ("H_start", "start_positions")):
        ref = tessellate(domain, [Generator(np.array(p)) for p in data[where]])
        assert data[key] == pytest.approx(ref.cost, rel=1e-6), key  # positions: 4 decimals
    ref = tessellate(domain, [Generator(np.array(p)) for p in data["positions"]])
    assert np.allclose(data["masses"], ref.masses, atol=2e-6)


def test_euclidean_team_plan_imports_no_scipy(tmp_path):
    code = ("import sys; from coverage_ros.cli.plan import main; "
            f"rc = main(['--map', 'gaussians', '--robots', '4', '--strategy', 'lloyd', "
            f"'--solver', 'lloyd', '--max-iterations', '5', '--json', "
            f"{str(tmp_path / 'p.json')!r}, '--quiet']); "
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy')); "
            "sys.exit(rc)")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_unknown_strategy_is_refused_with_the_names(capsys):
    assert main(["--map", "gaussians", "--robots", "2", "--strategy", "nope", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "unknown strategy" in err and "lloyd" in err
