"""The geodesic team step as one tessellation (coverage_ros.core.offline.geodesic_team) gives
every robot the cell, sums and control of its own decentralized update over the whole domain
(GeodesicTeam.reference_step: geodesic_cell per robot)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import WORLDS, random_points, shared_map

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.euclidean import euclidean_labels
from coverage_ros.core.geodesic.tessellation import Generator, tessellate
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.lloyd_team import GeodesicTeam, TeamStep, solve_lloyd
from coverage_ros.core.world import load_world
from coverage_ros.core.world.grid import OCCUPIED, GridMap
from coverage_ros.core.world.placement import team_starts


def _domain(world: str, connectivity: int = 8) -> CoverageDomain:
    path = WORLDS / f"{world}.yaml" if (WORLDS / f"{world}.yaml").exists() else shared_map(world)
    return world_domain(load_world(path), 0.105, connectivity=connectivity)


def _assert_same(fast: TeamStep, ref: TeamStep) -> None:
    assert np.array_equal(fast.labels, ref.labels)
    assert np.allclose(fast.masses, ref.masses, rtol=1e-12, atol=0.0)
    assert np.allclose(fast.costs, ref.costs, rtol=1e-10, atol=1e-12)
    assert np.allclose(fast.centroids, ref.centroids, rtol=0.0, atol=1e-9)
    assert np.allclose(fast.goals, ref.goals, rtol=0.0, atol=1e-9)


def _reference(team: GeodesicTeam, P: np.ndarray, R: np.ndarray) -> TeamStep:
    team.domain._cache.pop("shared_search", None)  # the robots' own search, not the team's
    return team.reference_step(P, R)


@pytest.mark.parametrize("world, connectivity, method, seed, blocked", [
    ("office", 8, "auto", 1, 0), ("office", 16, "auto", 2, 1), ("u_shape", 8, "auto", 3, 0),
    ("field", 8, "auto", 4, 1), ("depot", 8, "auto", 5, 1), ("depot", 16, "auto", 6, 0),
    ("office", 8, "paper", 7, 0), ("u_shape", 16, "lookahead", 8, 1),
    ("depot", 8, "lookahead", 9, 0),
])
def test_team_step_equals_every_robots_own_update(world, connectivity, method, seed, blocked):
    domain = _domain(world, connectivity)
    P = random_points(domain, 7 - blocked, blocked, seed)
    R = np.zeros(len(P))
    team = GeodesicTeam(domain, method)
    fast = team.step(P, R)
    _assert_same(fast, _reference(team, P, R))
    gens = [Generator(p) for p in P]
    assert np.array_equal(fast.labels, tessellate(domain, gens, method).labels)
    if world in ("office", "depot"):  # walls: cells hidden from their robot were searched
        assert (fast.labels != euclidean_labels(domain, gens)).any()


@pytest.mark.parametrize("world, connectivity, method, seed", [
    ("office", 8, "auto", 11), ("u_shape", 16, "auto", 12), ("depot", 8, "auto", 13),
    ("office", 8, "lookahead", 14),
])
def test_power_team_step_equals_every_robots_own_update(world, connectivity, method, seed):
    domain = _domain(world, connectivity)
    P = random_points(domain, 5, 0, seed)
    R = np.random.default_rng(seed).uniform(0.0, 1.5, len(P))
    team = GeodesicTeam(domain, method)
    fast = team.step(P, R)
    _assert_same(fast, _reference(team, P, R))


def test_robots_on_cell_centres_tie_as_their_own_updates():
    """Robots on cell centres leave cells exactly as far from two of them: the tie bias gives
    each such cell to the same robot in the team step as in the robots' own updates."""
    occ = np.zeros((60, 80), dtype=np.int8)
    occ[20:40, 30:34] = OCCUPIED  # a wall in the middle, with cells hidden behind it
    domain = CoverageDomain.from_grid(GridMap(occ, 0.1, (0.0, 0.0, 0.0)), 0.0)
    P = domain.to_map(np.array([[10.5, 30.5], [50.5, 30.5], [30.5, 10.5], [30.5, 50.5],
                                [70.5, 10.5]]))
    team = GeodesicTeam(domain)
    R = np.zeros(len(P))
    _assert_same(team.step(P, R), _reference(team, P, R))


def test_a_robot_with_an_empty_cell_stays():
    """Two robots at one point: the first in source order keeps the cell, the other has no
    mass and stays (each robot's own update would claim the cell for itself)."""
    domain = _domain("u_shape")
    P = random_points(domain, 3, 0, 21)
    team = GeodesicTeam(domain)
    alone = team.step(P)
    twice = team.step(np.vstack([P, P[:1]]))
    assert np.array_equal(twice.labels, alone.labels)
    assert np.array_equal(twice.masses[:3], alone.masses)
    assert np.array_equal(twice.centroids[:3], alone.centroids)
    assert twice.masses[3] == 0.0 and twice.costs[3] == 0.0
    assert np.array_equal(twice.centroids[3], P[0]) and np.array_equal(twice.goals[3], P[0])


def _lloyd_from_the_cluster(name: str, n: int):
    """A geodesic team of ``n`` robots on shipped world ``name`` from the launcher's start
    cluster (seed 0), with its specs, starts and plain Lloyd run (2 cm tolerance)."""
    world = load_world(WORLDS / f"{name}.yaml")
    specs = [world.robot_spec(i) for i in range(n)]
    team = GeodesicTeam(world_domain(world, max(s.radius for s in specs)))
    starts = team_starts(world, specs, None, 0)[:, :2]
    return team, specs, starts, solve_lloyd(team, starts, tolerance=0.02, max_steps=300)


def test_plain_geodesic_lloyd_settles_where_full_steps_swing_across_doorways():
    """Six robots from the launcher's cluster in the office: full generalized Lloyd steps
    overshoot through the doorways and H swings for hundreds of steps; the monotone plain step
    (half the way, a quarter, ... where H would rise) never raises H and settles."""
    team, _, _, run = _lloyd_from_the_cluster("office", 6)
    assert run.converged and run.steps < 150
    E = np.array([team.step(P).cost for P in run.positions])  # H of the accepted positions
    assert np.all(np.diff(E) <= 1e-9 * E[:-1]), "an accepted step raised H"
    assert len(run.positions) < run.steps  # some full steps were refused (they count)
    assert E[-1] < 0.1 * E[0]


@pytest.mark.slow
def test_plain_geodesic_lloyd_ends_where_the_robots_own_updates_do():
    """Eight robots from the launcher's cluster in the ward: the team solver's monotone step
    halves only the steps of the robots whose cells' cost rose, as each robot's own monotone
    step does in the offline runner, and ends at the runner's H (escape off, so Lloyd alone on
    both sides). Halving every robot's step whenever H rises stops the team early (H 30 %
    higher here)."""
    from coverage_ros.core.offline.runner import OfflineConfig, run_offline
    from coverage_ros.core.strategies import StrategyContext, strategy_choice

    team, specs, starts, run = _lloyd_from_the_cluster("ward", 8)
    domain = team.domain
    choice = strategy_choice("geodesic", {"escape": False}, "test")
    contexts = [StrategyContext(domain=domain, robot=specs[i], robot_id=i,
                                convergence_tolerance=0.02) for i in range(8)]
    own = run_offline(domain, choice, starts, contexts=contexts,
                      config=OfflineConfig(max_iterations=300))
    H_own = team.step(own.positions[-1]).cost
    assert run.converged and own.converged
    assert abs(run.cost / H_own - 1.0) < 0.02, (run.cost, H_own)
