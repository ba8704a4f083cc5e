"""The whole-domain shared search that settles cells by line of sight first
(coverage_ros.core.geodesic.visible_first) gives every robot the same cell, distances and
control as its own pruned search and as the centralized tessellation."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import WORLDS, random_points, shared_map

from coverage_ros.core.geodesic.cell import geodesic_cell
from coverage_ros.core.geodesic.euclidean import euclidean_labels
from coverage_ros.core.geodesic.tessellation import Generator, fast_tessellate, tessellate
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.world import load_world


@pytest.mark.parametrize("world, seed, blocked", [
    ("office", 1, 0), ("office", 2, 2), ("l_shape", 3, 1), ("u_shape", 4, 0),
    ("gaussians", 5, 0),
])
def test_shared_search_cells_equal_each_robots_own_search(world, seed, blocked):
    domain = world_domain(load_world(WORLDS / f"{world}.yaml"), 0.105)
    P = random_points(domain, 6 - blocked, blocked, seed)
    gens = [Generator(p) for p in P]
    tess = tessellate(domain, gens)
    labels = np.full(domain.shape, -1)
    for i, g in enumerate(gens):
        others = gens[:i] + gens[i + 1:]
        shared = geodesic_cell(domain, g, others, whole=True)
        own = geodesic_cell(domain, g, others)  # pruned local search, its own code path
        assert np.array_equal(np.sort(shared.nodes), np.sort(own.nodes))
        order_s, order_o = np.argsort(shared.nodes), np.argsort(own.nodes)
        assert np.allclose(shared.distances[order_s], own.distances[order_o], rtol=1e-12,
                           atol=1e-12)
        assert shared.mass == pytest.approx(own.mass, rel=1e-12)
        assert shared.cost == pytest.approx(own.cost, rel=1e-9)
        assert np.allclose(shared.covector, own.covector, rtol=1e-9, atol=1e-12)
        assert np.allclose(shared.goal, own.goal, atol=1e-9)
        labels.ravel()[shared.nodes] = i
    assert np.array_equal(labels, tess.labels)
    if world in ("office", "u_shape"):
        # walls make some geodesic cells differ from the straight-line ones: the search of the
        # cells hidden from their nearest robot ran, not only the line-of-sight shortcut
        assert (tess.labels != euclidean_labels(domain, gens)).any()


def test_one_search_is_kept_per_domain():
    domain = world_domain(load_world(WORLDS / "l_shape.yaml"), 0.105)
    for seed in range(4):
        gens = [Generator(p) for p in random_points(domain, 3, 0, seed)]
        geodesic_cell(domain, gens[0], gens[1:], whole=True)
    assert sum(1 for k in domain._cache if "shared" in str(k)) == 1


@pytest.mark.parametrize("world, seed, blocked", [
    ("office", 6, 1), ("u_shape", 7, 0), ("tb3_sandbox", 8, 0), ("depot", 9, 2),
    ("gaussians", 10, 0),  # (free cells filling a rectangle: every one settled at once)
])
def test_fast_tessellation_is_the_centralized_one(world, seed, blocked):
    """fast_tessellate (the launcher's and the viewer's score) gives tessellate's labels,
    distances, masses and costs; with unequal power weights it is tessellate itself."""
    path = WORLDS / f"{world}.yaml" if (WORLDS / f"{world}.yaml").exists() else shared_map(world)
    domain = world_domain(load_world(path), 0.105)
    P = random_points(domain, 12 - blocked, blocked, seed)
    gens = [Generator(p) for p in P]
    fast, ref = fast_tessellate(domain, gens), tessellate(domain, gens)
    assert np.array_equal(fast.labels, ref.labels)
    mine = ref.labels >= 0
    assert np.allclose(fast.distances[mine], ref.distances[mine], rtol=1e-12, atol=1e-12)
    assert np.isinf(fast.distances[~mine]).all()
    assert np.allclose(fast.masses, ref.masses, rtol=1e-12)
    assert fast.cost == pytest.approx(ref.cost, rel=1e-12)
    if world in ("office", "depot"):  # walls: the hidden cells' search ran
        assert (ref.labels != euclidean_labels(domain, gens)).any()
    weighted = [Generator(p, 0.3 * (k % 2)) for k, p in enumerate(P)]
    fast, ref = fast_tessellate(domain, weighted), tessellate(domain, weighted)
    assert np.array_equal(fast.labels, ref.labels) and fast.cost == ref.cost


@pytest.mark.parametrize("world, capacity", [("office", None), ("u_shape", 16),
                                             ("tb3_sandbox", None)])
def test_depth_maps_kept_between_searches_change_no_cell(world, capacity):
    """Searches from generators that stand where one stood before (the descent's starts,
    a move priced again and again) use the depth maps the domain kept; a domain that keeps
    none gives bit for bit the same cells, distances and goals (also when the kept maps
    are evicted: ``capacity``)."""
    from coverage_ros.core.offline.geodesic_team import team_cells

    path = WORLDS / f"{world}.yaml" if (WORLDS / f"{world}.yaml").exists() else shared_map(world)
    kept, fresh = (world_domain(load_world(path), 0.105) for _ in range(2))
    if capacity is not None:
        kept.kept_depth_maps().capacity = capacity
    rng = np.random.default_rng(3)
    P = random_points(kept, 8, 0, 11)
    R = np.zeros(len(P))
    for step in range(12):
        Q = P.copy()
        if step % 3 == 0:  # one robot elsewhere, the others where they stood
            Q[step % len(P)] = random_points(kept, 1, 0, 100 + step)[0]
        else:  # some move a little (where a step leaves free space)
            moved = Q + rng.normal(0.0, 0.2, Q.shape) * (rng.random(len(Q)) < 0.5)[:, None]
            free = np.array([kept.is_free_point(q) for q in moved])
            Q[free] = moved[free]
        fresh._cache.pop("kept_depth_maps", None)
        a, b = team_cells(kept, Q, R), team_cells(fresh, Q, R)
        assert np.array_equal(a.cells(), b.cells())
        assert np.array_equal(a.costs, b.costs) and np.array_equal(a.masses, b.masses)
        assert np.array_equal(a.covectors, b.covectors) and np.array_equal(a.goals, b.goals)
        if step % 2 == 0:
            P = Q
    assert len(kept.kept_depth_maps()) > len(P)  # (maps of earlier positions are kept)


def test_a_domain_with_kept_depth_maps_copies_and_pickles():
    import copy
    import pickle

    domain = world_domain(load_world(WORLDS / "office.yaml"), 0.105)
    gens = [Generator(p) for p in random_points(domain, 4, 0, 5)]
    fast_tessellate(domain, gens)
    kept = domain.kept_depth_maps()
    kept.capacity = 40
    assert len(kept) > 0
    for other in (copy.deepcopy(domain), pickle.loads(pickle.dumps(domain))):
        again = other.kept_depth_maps()
        assert again.capacity == 40 and list(again) == list(kept)
        assert np.array_equal(fast_tessellate(other, gens).labels,
                              fast_tessellate(domain, gens).labels)
