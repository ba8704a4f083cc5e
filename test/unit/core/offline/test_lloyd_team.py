"""The vectorized team Lloyd step and the plain / accelerated Lloyd solvers
(coverage_ros.core.offline.lloyd_team)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import NO_ESCAPE, WORLDS

from coverage_ros.cli.plan import main
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.euclidean import euclidean_cell, euclidean_labels
from coverage_ros.core.geodesic.tessellation import Generator
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.lloyd_team import EuclideanTeam, solve_lloyd
from coverage_ros.core.world import load_world
from coverage_ros.core.world.density import GaussianMixture
from coverage_ros.core.world.grid import OCCUPIED, GridMap
from coverage_ros.errors import ConfigError


def _open_square(side_cells: int, resolution: float = 0.05, yaw: float = 0.0) -> CoverageDomain:
    occ = np.zeros((side_cells, side_cells), dtype=np.int8)
    return CoverageDomain.from_grid(GridMap(occ, resolution, (1.0, -2.0, yaw)), 0.0)


@pytest.fixture(scope="module")
def field():
    world = load_world(WORLDS / "field.yaml")  # obstacles and a Gaussian-mixture density
    return world_domain(world, 0.105)


def _free_points(domain: CoverageDomain, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    xmin, ymin, xmax, ymax = domain.geometry.extent()
    pts = []
    while len(pts) < n:
        p = rng.uniform([xmin, ymin], [xmax, ymax])
        if domain.is_free_point(p):
            pts.append(p)
    return np.array(pts)


@pytest.mark.parametrize("seed, weighted", [(1, False), (2, True), (3, False)])
def test_team_step_equals_every_robots_decentralized_update(field, seed, weighted):
    P = _free_points(field, 6, seed)
    R = np.random.default_rng(seed).uniform(0.0, 1.5, 6) if weighted else np.zeros(6)
    step = EuclideanTeam(field).step(P, R)
    gens = [Generator(p, r) for p, r in zip(P, R, strict=True)]
    assert np.array_equal(step.labels, euclidean_labels(field, gens))
    for i, g in enumerate(gens):
        cell = euclidean_cell(field, g, gens[:i] + gens[i + 1:])
        assert step.masses[i] == pytest.approx(cell.mass, rel=1e-9)
        assert step.costs[i] == pytest.approx(cell.cost, rel=1e-7, abs=1e-9)
        assert np.allclose(step.centroids[i], cell.centroid, atol=1e-9)
        assert np.allclose(step.goals[i], cell.goal, atol=1e-9)


def test_a_cell_in_the_far_tail_of_the_density_has_its_own_centroid():
    """A robot whose cell holds only the far tail of a narrow Gaussian (mass ~1e-56 beside
    cells of mass ~1 on the same rows): its centroid and goal are the decentralized update's,
    inside its cell, not the rounding of the heavy cells' running sums."""
    occ = np.zeros((200, 200), dtype=np.int8)
    density = GaussianMixture(np.array([[1.0, 5.0]]), np.array([np.diag([0.3 ** 2] * 2)]),
                              np.array([1.0]))
    domain = CoverageDomain.from_grid(GridMap(occ, 0.05, (0.0, 0.0, 0.0)), 0.0, density)
    P = np.array([[1.0, 5.0], [2.0, 4.0], [2.0, 6.0], [9.5, 5.0]])
    step = EuclideanTeam(domain).step(P)
    gens = [Generator(p) for p in P]
    far = euclidean_cell(domain, gens[3], gens[:3])
    assert 0.0 < step.masses[3] < 1e-30  # the case: a cell of next to no mass
    assert step.masses[3] == pytest.approx(far.mass, rel=1e-9)
    assert np.allclose(step.centroids[3], far.centroid, atol=1e-9)
    assert np.allclose(step.goals[3], far.goal, atol=1e-9)
    assert domain.is_free_point(step.goals[3])


def test_projection_of_a_centroid_on_an_obstacle():
    occ = np.zeros((40, 40), dtype=np.int8)
    occ[15:25, 15:25] = OCCUPIED  # a block in the middle: one robot's centroid falls on it
    domain = CoverageDomain.from_grid(GridMap(occ, 0.1, (0.0, 0.0, 0.0)), 0.0)
    step = EuclideanTeam(domain).step(np.array([[0.5, 0.5]]))
    assert np.allclose(step.centroids[0], [2.0, 2.0], atol=1e-9)  # the square's centre
    assert domain.is_free_point(step.goals[0])
    # the nearest free cell centre to it: beside the block, e.g. (1.45, 1.95)
    assert np.hypot(*(step.goals[0] - [2.0, 2.0])) == pytest.approx(np.hypot(0.55, 0.05))


@pytest.mark.parametrize("yaw", [0.0, 0.7])
def test_one_robot_in_a_uniform_square_analytic(yaw):
    domain = _open_square(100, yaw=yaw)  # 5 m x 5 m, rotated and moved: frame-independent
    centre = domain.to_map(np.array([[50.0, 50.0]]))[0]
    step = EuclideanTeam(domain).step(centre[None, :])
    L = 5.0
    assert step.masses[0] == pytest.approx(L * L, rel=1e-12)
    # int over the square of |q - centre|^2 = L^4 / 6; the cell-centre rule adds h^2 L^2 / 6
    assert step.cost == pytest.approx(L ** 4 / 6 - 0.05 ** 2 * L * L / 6, rel=1e-9)
    assert np.allclose(step.centroids[0], centre, atol=1e-9)


def test_gradient_is_twice_mass_times_offset_from_the_centroid(field):
    P = _free_points(field, 5, 7)
    team = EuclideanTeam(field)
    step = team.step(P)
    grad = 2.0 * step.masses[:, None] * (P - step.centroids)
    h = 1e-4
    for i in range(5):
        for k in range(2):
            Pp, Pm = P.copy(), P.copy()
            Pp[i, k] += h
            Pm[i, k] -= h
            fd = (team.step(Pp).cost - team.step(Pm).cost) / (2 * h)
            assert fd == pytest.approx(grad[i, k], rel=2e-3, abs=1e-6 * step.masses[i])


@pytest.fixture(scope="module")
def scale_runs():
    """Plain and accelerated Lloyd on the shipped scale scenario (402 x 402 cells, 8 robots)."""
    world = load_world(WORLDS / "gaussians.yaml")
    domain = world_domain(world, 0.105)
    starts = np.array([[s.x, s.y] for s in world.starts])
    team = EuclideanTeam(domain)
    runs = {s: solve_lloyd(team, starts, solver=s, tolerance=0.005, max_steps=1000)
            for s in ("lloyd", "accelerated")}
    runs["team"] = team
    return runs


def test_plain_lloyd_never_raises_the_energy_and_converges(scale_runs):
    run = scale_runs["lloyd"]
    assert run.converged and run.steps == len(run.energies) == len(run.positions)
    E = np.array(run.energies)
    assert np.all(np.diff(E) <= 1e-9 * E[:-1]), "a Lloyd step raised H"
    assert run.last.step_length < 0.005
    assert E[-1] < 0.05 * E[0]  # from the corner to the three Gaussians


def test_accelerated_lloyd_reaches_the_same_energy_in_fewer_steps(scale_runs):
    plain, fast = scale_runs["lloyd"], scale_runs["accelerated"]
    assert fast.converged
    assert fast.cost <= 1.001 * plain.cost
    assert fast.steps < plain.steps
    assert fast.steps_within(plain.cost) < plain.steps_within(plain.cost)
    # the safeguard: the energy of the accepted positions never rises
    E = np.array([scale_runs["team"].step(P).cost for P in fast.positions])
    assert np.all(np.diff(E) <= 1e-9 * E[:-1])
    assert len(fast.positions) <= fast.steps  # rejected extrapolations count as steps


def test_unknown_solver_is_refused(field):
    with pytest.raises(ConfigError, match="solver"):
        solve_lloyd(EuclideanTeam(field), _free_points(field, 2, 0), solver="newton")


def test_coverage_plan_solver_option(tmp_path, capsys):
    out = tmp_path / "p.json"
    assert main(["--map", "field", "--robots", "4", "--strategy", "lloyd", "--solver",
                 "accelerated", "--json", str(out), "--quiet"]) == 0
    data = json.loads(out.read_text())
    assert data["solver"] == "accelerated" and data["converged"]
    assert data["iterations"] >= 1 and data["wall_time_s"] > 0 and 0 < data["H"] < data["H_start"]
    assert main(["--map", "field", "--robots", "4", "--strategy", "tangentbug", "--solver",
                 "lloyd", "--quiet"]) == 2
    assert "--solver: needs --strategy lloyd or geodesic" in capsys.readouterr().err


@pytest.mark.slow
def test_geodesic_team_solver_reaches_the_decentralized_runs_cost(tmp_path):
    """coverage-plan --strategy geodesic: the whole team's step (one shared search per step)
    ends where every robot's own updates end, at the same cost. (The robots' own updates
    without the closet escape, which the team solvers do not make: plain generalized Lloyd on
    both sides; on this map the three end within 0.02 % of each other.)"""
    runs = {}
    for solver in ("decentralized", "lloyd", "accelerated"):
        out = tmp_path / f"{solver}.json"
        params = list(NO_ESCAPE) if solver == "decentralized" else []
        assert main(["--map", "l_shape", "--robots", "4", "--strategy", "geodesic", "--solver",
                     solver, *params, "--json", str(out), "--quiet"]) == 0
        runs[solver] = json.loads(out.read_text())
    ref = runs["decentralized"]
    for solver in ("lloyd", "accelerated"):
        assert runs[solver]["converged"]
        assert runs[solver]["H"] == pytest.approx(ref["H"], rel=2e-3), (solver, runs)
        assert runs[solver]["H"] < 0.5 * ref["H_start"]
