"""Robots of one process share whole-map searches (``geodesic_cell(..., reuse=)``, robot_node
``search_reuse``): a robot takes its cell from a sibling's search of a team that near, the
exact cell of that team; never its own search nor one it has steered by already."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import WORLDS

from coverage_ros.core.geodesic.cell import SearchCache, geodesic_cell
from coverage_ros.core.geodesic.tessellation import Generator, tessellate
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.world import cluster_starts, load_world

REUSE = 0.1  # [m]


def _team(seed: int, count: int = 7):
    """A team bunched up in the office (its outer robots search the whole map)."""
    world = load_world(WORLDS / "office.yaml")
    domain = world_domain(world, 0.105)
    starts = cluster_starts(world.grid, count, 0.105, np.random.default_rng(seed))
    return domain, [Generator(p) for p in starts[:, :2]]


def _nudged(gens, rng, most: float):
    """The team a moment later: every robot moved by up to ``most`` [m]."""
    step = rng.uniform(-1.0, 1.0, (len(gens), 2))
    step *= most / np.maximum(np.hypot(step[:, 0], step[:, 1]), 1.0)[:, None] * 0.99
    return [Generator(g.position + s) for g, s in zip(gens, step, strict=True)]


def _whole_map_searcher(domain, gens) -> int:
    """A robot whose update searches the whole map (its cell is most of it)."""
    for k in range(len(gens)):
        cell = geodesic_cell(domain, gens[k], gens[:k] + gens[k + 1:], cache=SearchCache())
        if cell.searched_nodes == domain.shape[0] * domain.shape[1]:
            return k
    raise AssertionError("no robot of the bunched team searched the whole map")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_robot_takes_the_exact_cell_of_a_siblings_search_of_a_team_that_near(seed):
    domain, gens = _team(seed)
    rng = np.random.default_rng(seed)
    a = _whole_map_searcher(domain, gens)
    geodesic_cell(domain, gens[a], gens[:a] + gens[a + 1:], cache=SearchCache(), reuse=REUSE)
    tess = tessellate(domain, gens)
    later = _nudged(gens, rng, REUSE)
    b = (a + 1) % len(gens)
    # b's own view: itself first, the others in another order (as its neighbour table has them)
    order = [k for k in rng.permutation(len(gens)) if k != b]
    cache = SearchCache()
    cell = geodesic_cell(domain, later[b], [later[k] for k in order], cache=cache, reuse=REUSE)
    assert cell.passes == 0  # no search of its own
    assert set(cell.nodes.tolist()) == set(np.flatnonzero(tess.labels.ravel() == b).tolist())
    exact = geodesic_cell(domain, gens[b], gens[:b] + gens[b + 1:])
    np.testing.assert_allclose(cell.goal, exact.goal)
    np.testing.assert_allclose(cell.covector, exact.covector, rtol=1e-9, atol=1e-12)
    # neighbours: indices into b's own list, mapped back through the matching
    others_exact = [k for k in range(len(gens)) if k != b]
    assert {order[k] for k in cell.neighbours} == {others_exact[k] for k in exact.neighbours}
    # the next update, with nobody's search made since: its own search of its own view
    again = geodesic_cell(domain, later[b], [later[k] for k in order], cache=cache,
                          reuse=REUSE)
    assert again.passes >= 1
    mine = tessellate(domain, [later[b]] + [later[k] for k in order]).labels.ravel()
    assert set(again.nodes.tolist()) == set(np.flatnonzero(mine == 0).tolist())


def test_a_team_farther_than_the_reuse_distance_is_searched_again():
    domain, gens = _team(3)
    a = _whole_map_searcher(domain, gens)
    geodesic_cell(domain, gens[a], gens[:a] + gens[a + 1:], reuse=REUSE)
    later = list(gens)
    b = (a + 1) % len(gens)
    c = (a + 2) % len(gens)
    later[c] = Generator(gens[c].position + np.array([REUSE * 1.5, 0.0]))  # one robot too far
    cell = geodesic_cell(domain, later[b], later[:b] + later[b + 1:], cache=SearchCache(),
                         reuse=REUSE)
    assert cell.passes >= 1
    mine = tessellate(domain, later).labels.ravel()
    assert set(cell.nodes.tolist()) == set(np.flatnonzero(mine == b).tolist())


def test_a_robot_alone_in_its_domain_never_steers_by_an_old_search():
    domain, gens = _team(4)
    rng = np.random.default_rng(4)
    a = _whole_map_searcher(domain, gens)
    domain._cache.pop("shared_search")
    cache = SearchCache()
    view = gens
    for _ in range(3):
        cell = geodesic_cell(domain, view[a], view[:a] + view[a + 1:], cache=cache,
                             reuse=REUSE)
        assert cell.passes >= 1
        labels = tessellate(domain, view).labels.ravel()
        assert set(cell.nodes.tolist()) == set(np.flatnonzero(labels == a).tolist())
        view = _nudged(view, rng, REUSE / 2)


def test_without_reuse_only_the_very_same_team_shares_a_search():
    domain, gens = _team(5)
    a = _whole_map_searcher(domain, gens)
    geodesic_cell(domain, gens[a], gens[:a] + gens[a + 1:])
    later = _nudged(gens, np.random.default_rng(5), 0.08)
    then, now = tessellate(domain, gens).labels.ravel(), tessellate(domain, later).labels.ravel()
    for b in range(len(gens)):
        if b == a or np.array_equal(then == b, now == b):
            continue  # (a robot whose cell the nudge left as it was tells nothing)
        cell = geodesic_cell(domain, later[b], later[:b] + later[b + 1:], cache=SearchCache())
        assert set(cell.nodes.tolist()) == set(np.flatnonzero(now == b).tolist()), b
        same = geodesic_cell(domain, gens[b], gens[:b] + gens[b + 1:], cache=SearchCache())
        assert set(same.nodes.tolist()) == set(np.flatnonzero(then == b).tolist()), b


def test_two_robots_at_one_point_still_get_their_cells():
    """(The kept search cannot match them one to one by position: it is searched again. Which
    twin a tied cell goes to is arbitrary.)"""
    domain, gens = _team(6)
    a = _whole_map_searcher(domain, gens)
    twin = (a + 1) % len(gens)
    gens[twin] = Generator(gens[a].position.copy())
    labels = tessellate(domain, gens).labels.ravel()
    common = set(np.flatnonzero((labels == a) | (labels == twin)).tolist())
    assert len(common) > 100
    for k in (a, twin):
        for _ in range(2):
            cell = geodesic_cell(domain, gens[k], gens[:k] + gens[k + 1:], cache=SearchCache(),
                                 reuse=REUSE)
            assert set(cell.nodes.tolist()) <= common, k
