"""The team Lloyd step from row runs of the power cells (coverage_ros.core.offline.power_rows)
against the obvious one that labels every grid cell (EuclideanTeam.reference_step)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import WORLDS

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.lloyd_team import EuclideanTeam
from coverage_ros.core.offline.power_rows import NEIGHBOURS_FROM, neighbour_pairs
from coverage_ros.core.world import load_world
from coverage_ros.core.world.grid import GridMap


@pytest.fixture(scope="module")
def field_team():
    world = load_world(WORLDS / "field.yaml")  # obstacles and a Gaussian-mixture density
    return EuclideanTeam(world_domain(world, 0.105))


def _points(domain: CoverageDomain, n: int, rng: np.random.Generator) -> np.ndarray:
    xmin, ymin, xmax, ymax = domain.geometry.extent()
    return rng.uniform([xmin, ymin], [xmax, ymax], (n, 2))


def _same(fast, ref) -> None:
    assert np.array_equal(fast.labels, ref.labels)
    total = ref.masses.sum()
    assert np.allclose(fast.masses, ref.masses, rtol=0, atol=1e-11 * total)
    assert np.allclose(fast.costs, ref.costs, rtol=1e-9, atol=1e-11 * abs(ref.costs).sum())
    assert np.allclose(fast.centroids, ref.centroids, rtol=0, atol=1e-9)
    assert np.allclose(fast.goals, ref.goals, rtol=0, atol=1e-9)


@pytest.mark.parametrize("n", [1, 2, 5, NEIGHBOURS_FROM - 1, NEIGHBOURS_FROM, 40])
@pytest.mark.parametrize("weighted", [False, True])
def test_row_runs_step_equals_labelling_every_cell(field_team, n, weighted):
    rng = np.random.default_rng(100 * n + weighted)
    for _ in range(3):
        P = _points(field_team.domain, n, rng)  # on obstacles too: projected goals
        R = rng.uniform(0.0, 1.5, n) if weighted else None
        _same(field_team.step(P, R), field_team.reference_step(P, R))


def test_projection_is_exercised_and_agrees(field_team):
    """Robots far apart on the obstacle map: centroids on blocked cells, goals moved."""
    rng = np.random.default_rng(5)
    moved = 0
    for _ in range(10):
        P = _points(field_team.domain, 6, rng)
        fast, ref = field_team.step(P), field_team.reference_step(P)
        _same(fast, ref)
        moved += int((np.hypot(*(fast.goals - fast.centroids).T) > 1e-9).sum())
        assert all(field_team.domain.is_free_point(q) for q in fast.goals)
    assert moved > 0


@pytest.mark.parametrize("n", [3, NEIGHBOURS_FROM + 4])
def test_degenerate_placements(field_team, n):
    """Robots in a column (equal x: parallel bounds, a flat lifted hull), on a line and on the
    same spot (the lower index takes the cell)."""
    rng = np.random.default_rng(n)
    P = _points(field_team.domain, n, rng)
    column = P.copy()
    column[:, 0] = column[0, 0]
    line = np.stack([np.linspace(1, 9, n), np.linspace(2, 6, n)], axis=1)
    twins = P.copy()
    twins[1] = twins[0]
    for Q in (column, line, twins):
        _same(field_team.step(Q), field_team.reference_step(Q))
    assert field_team.step(twins).masses[1] == 0.0


@pytest.mark.parametrize("order", [1, -1])
def test_cell_centre_on_a_boundary_goes_to_the_lower_index(order):
    """Exact binary numbers: the bisector of robots at x = 10.5 and 20.5 m passes through the
    centres of column 15 (resolution 1 m)."""
    domain = CoverageDomain.from_grid(GridMap(np.zeros((30, 40), dtype=np.int8), 1.0,
                                              (0.0, 0.0, 0.0)), 0.0)
    team = EuclideanTeam(domain)
    P = np.array([[10.5, 12.5], [20.5, 12.5]])[::order]
    fast, ref = team.step(P), team.reference_step(P)
    _same(fast, ref)
    assert np.all(fast.labels[:, 15] == 0)


def test_neighbour_pairs_are_the_delaunay_edges_with_equal_weights():
    rng = np.random.default_rng(3)
    P = rng.uniform(0, 10, (30, 2))
    k, j = neighbour_pairs(P[:, 0], P[:, 1], np.zeros(30))
    edges = set(zip(k.tolist(), j.tolist(), strict=True))
    assert all((b, a) in edges for a, b in edges)
    assert list(k) == sorted(k)
    # every robot's nearest other robot is a Delaunay neighbour
    d = np.hypot(*(P[:, None] - P[None]).transpose(2, 0, 1)) + np.eye(30) * 1e9
    assert all((i, int(np.argmin(d[i]))) in edges for i in range(30))
    line = np.stack([np.arange(5.0), np.arange(5.0)], axis=1)
    assert neighbour_pairs(line[:, 0], line[:, 1], np.zeros(5)) is None
