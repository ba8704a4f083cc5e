"""Whole-map searches from points: kept source rows give the rows made for each radius, and the
multi-source search is the least of single-source searches."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.local_search import local_graph_for
from coverage_ros.core.geodesic.tessellation import source_row
from coverage_ros.core.geodesic.whole_map import (
    SourceRows,
    cell_cost_about,
    nearest,
    source_rows,
)
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.world import load_world
from coverage_ros.worlds import resolve_world_path


@cache
def office() -> CoverageDomain:
    world = load_world(resolve_world_path("office", "--map"))
    return world_domain(world, world.robot_spec(0).radius)


def free_points(domain: CoverageDomain, n: int, seed: int) -> np.ndarray:
    rows, cols = np.nonzero(domain.free)
    pick = np.random.default_rng(seed).choice(len(rows), size=n, replace=False)
    # off the cell centres, so that a source joins several cells
    jitter = np.random.default_rng(seed + 1).uniform(-0.4, 0.4, size=(n, 2))
    return domain.to_map(np.column_stack([cols[pick] + 0.5, rows[pick] + 0.5]) + jitter)


def direct_row(domain: CoverageDomain, point: np.ndarray, radius: float):
    local = local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1), math.inf)
    return source_row(domain, local, domain.snap(point), radius, "visibility")


def test_a_kept_row_serves_every_smaller_radius_as_if_made_for_it():
    domain = office()
    rows = SourceRows(domain, "auto")
    for p in free_points(domain, 6, 0):
        for radius in (math.inf, 4.0, 1.0, 2.5, 0.3):  # the largest first: the rest filtered
            lids, costs = rows.row(p, radius)
            want_lids, want_costs = direct_row(domain, p, radius)
            np.testing.assert_array_equal(lids, want_lids)
            np.testing.assert_array_equal(costs, want_costs)
    assert rows.made == 6  # one row per point


def test_a_row_asked_at_a_larger_radius_is_made_again_and_the_oldest_go_beyond_capacity():
    domain = office()
    p, q, r = free_points(domain, 3, 1)
    rows = SourceRows(domain, "auto", capacity=1)
    small = rows.row(p, 0.5)
    assert rows.made == 1 and rows.row(p, 0.5)[0] is small[0]
    lids, _ = rows.row(p, 3.0)
    assert rows.made == 2 and len(lids) > len(small[0])
    np.testing.assert_array_equal(lids, direct_row(domain, p, 3.0)[0])
    rows.row(q, 1.0)
    rows.row(r, 1.0)
    assert rows.made == 4 and len(rows._rows) == 1  # only the latest kept
    rows.row(p, 3.0)
    assert rows.made == 5  # made again once dropped


def test_a_row_made_again_at_a_larger_radius_is_the_newest():
    domain = office()
    p, q = free_points(domain, 2, 4)
    rows = SourceRows(domain, "auto")
    rows.row(p, 0.5)  # the oldest
    rows.row(q, 0.5)
    rows.capacity = len(rows.row(q, 0.5)[0]) + len(direct_row(domain, p, 3.0)[0])
    lids, _ = rows.row(p, 3.0)  # made again and kept; q, now the oldest, still fits
    np.testing.assert_array_equal(lids, direct_row(domain, p, 3.0)[0])
    assert list(rows._rows) == [tuple(q), tuple(p)] and rows.made == 3
    rows.capacity = len(lids)
    rows.row(q, 1.0)  # made again: p, the oldest now, goes
    assert list(rows._rows) == [tuple(q)] and rows.made == 4


def test_the_domain_keeps_one_row_cache_per_method():
    domain = office()
    assert source_rows(domain) is source_rows(domain, "visibility")
    assert source_rows(domain, "paper") is not source_rows(domain)


@pytest.mark.parametrize("limit", [math.inf, 3.0])
def test_the_nearest_of_several_points_is_the_least_of_their_own_searches(limit):
    domain = office()
    P = free_points(domain, 5, 2)
    d, label = nearest(domain, P, limit)
    local = local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1), math.inf)
    n = local.n
    each = np.array([dijkstra(local.with_sources([direct_row(domain, p, limit)]),
                              directed=True, indices=n + 1, limit=limit)[1:n + 1]
                     for p in P])
    np.testing.assert_array_equal(d, each.min(axis=0))
    reached = np.isfinite(d)
    assert reached.any() and (limit == math.inf or not reached[domain.free.ravel()].all())
    assert np.all(label[~reached] == -1)
    np.testing.assert_array_equal(each[label[reached], np.flatnonzero(reached)], d[reached])


def test_a_cells_cost_about_a_point_sums_its_distances_from_it():
    domain = office()
    p, q = free_points(domain, 2, 3)
    d, _ = nearest(domain, q[None], math.inf)
    nodes = np.flatnonzero(np.isfinite(d) & (d < 2.0))
    g, _ = nearest(domain, p[None], math.inf)
    want = float(((g[nodes] ** 2 - 0.1 ** 2) * domain.mass_element.ravel()[nodes]).sum())
    assert cell_cost_about(domain, nodes, p, 0.1, math.inf) == pytest.approx(want, rel=1e-12)
    assert cell_cost_about(domain, nodes, p, 0.1, 1e-3) == math.inf  # beyond the limit
