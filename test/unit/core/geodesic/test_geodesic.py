"""Geodesic power Voronoi tessellation and control (Bhattacharya et al. 2014): correctness
tests."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from conftest import WORLDS

from coverage_ros.core.geodesic.cell import COLD_STRIDE, SearchCache, cold_radius, geodesic_cell
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.graph import octile_bound
from coverage_ros.core.geodesic.local_search import SIGHT_WHOLE_SHARE, WHOLE_SHARE
from coverage_ros.core.geodesic.reference import obvious_cell, paper_cell
from coverage_ros.core.geodesic.tangents import (
    SIGHT_TILE,
    polar_depth,
    sight_tiles,
    tile_index,
    visible_from,
)
from coverage_ros.core.geodesic.tessellation import Generator, tessellate
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.world import cluster_starts, load_world
from coverage_ros.core.world.grid import OCCUPIED, GridMap
from coverage_ros.core.world.loading import parse_world

RES = 0.1


def empty_domain(h=40, w=50, connectivity=8) -> CoverageDomain:
    return CoverageDomain.from_grid(GridMap(np.zeros((h, w), np.int8), RES), 0.0,
                                    connectivity=connectivity)


#: The L-shaped obstacle of :func:`l_domain` [m]: a vertical bar and a bar on top of it.
BAR = (2.0, 1.0, 2.4, 3.0)
TOP = (0.8, 2.6, 2.4, 3.0)


def l_domain() -> CoverageDomain:
    """40 x 40 cells of 0.1 m with the L-shaped obstacle BAR + TOP."""
    occ = np.zeros((40, 40), np.int8)
    occ[10:30, 20:24] = OCCUPIED  # BAR: rows 10..29, cols 20..23
    occ[26:30, 8:24] = OCCUPIED  # TOP
    return CoverageDomain.from_grid(GridMap(occ, RES), 0.0)


def segment_hits_rect(p, q, rect) -> np.ndarray:
    """Whether the segments p -> q (q: (N, 2)) pass through the rectangle (dense sampling)."""
    x0, y0, x1, y1 = rect
    t = np.linspace(0.0, 1.0, 400)[None, :, None]
    pts = p[None, None, :] + t * (q[:, None, :] - p[None, None, :])
    inside = ((pts[..., 0] > x0) & (pts[..., 0] < x1) & (pts[..., 1] > y0) & (pts[..., 1] < y1))
    return inside.any(axis=1)


def random_domain(rng, h=30, w=36, blocks=5) -> CoverageDomain:
    occ = np.zeros((h, w), np.int8)
    for _ in range(blocks):
        r, c = rng.integers(0, h - 6), rng.integers(0, w - 6)
        occ[r:r + rng.integers(2, 7), c:c + rng.integers(2, 7)] = OCCUPIED
    return CoverageDomain.from_grid(GridMap(occ, RES), 0.0)


def random_generators(domain, rng, k, weights=False) -> list[Generator]:
    free = np.argwhere(domain.free)
    pick = free[rng.choice(len(free), k, replace=False)]
    pts = domain.geometry.cell_centers(pick) + rng.uniform(-0.4, 0.4, (k, 2)) * RES
    return [Generator(p, float(rng.uniform(0, 0.6)) if weights else 0.0) for p in pts]


def distances_from(domain, point, method):
    """Full distance field of one generator (a one-robot tessellation)."""
    return tessellate(domain, [Generator(np.asarray(point, float))], method).distances


# ---------------------------------------------------------------------------- distances
def test_free_space_distances_are_euclidean_with_visibility_sources():
    domain = empty_domain()
    p = np.array([1.23, 2.07])
    g = distances_from(domain, p, "visibility")
    X, Y = domain.geometry.all_cell_centers()
    assert np.allclose(g, np.hypot(X - p[0], Y - p[1]), atol=1e-9)


@pytest.mark.parametrize("connectivity", [8, 16])
def test_free_space_graph_distances_follow_the_neighbourhood_metric(connectivity):
    """Paper sources (cells around the point): the graph metric's exact values, within the
    neighbourhood's anisotropy bound of the Euclidean distance."""
    domain = empty_domain(connectivity=connectivity)
    p = np.array([2.05, 1.95])  # on a cell centre: one connection of length ~0
    g = distances_from(domain, p, "paper")
    X, Y = domain.geometry.all_cell_centers()
    d = np.hypot(X - p[0], Y - p[1])
    if connectivity == 8:
        dx, dy = np.abs(X - p[0]), np.abs(Y - p[1])
        octile = np.maximum(dx, dy) + (math.sqrt(2) - 1) * np.minimum(dx, dy)
        assert np.allclose(g, octile, atol=1e-9)
    assert np.all(g >= d - 1e-9)
    assert np.all(g <= octile_bound(connectivity) * d + 1e-9)
    assert octile_bound(8) == pytest.approx(1.0 / math.cos(math.pi / 8))


def test_distances_around_an_l_shaped_obstacle():
    domain = l_domain()
    p = np.array([3.05, 0.45])  # right of the bar and below it
    corner = np.array([BAR[0], BAR[1]])  # the geodesics into the L wrap its bottom-left corner
    g = distances_from(domain, p, "visibility")
    X, Y = domain.geometry.all_cell_centers()
    q = np.stack([X.ravel(), Y.ravel()], axis=-1)
    inside_l = ((X > TOP[0] + 0.1) & (X < BAR[0] - 0.05) & (Y < TOP[1] - 0.05)).ravel()
    hidden = (inside_l & segment_hits_rect(p, q, BAR)).reshape(X.shape) & domain.free
    analytic = np.hypot(*(corner - p)) + np.hypot(X - corner[0], Y - corner[1])
    assert hidden.sum() > 50
    excess = (g - analytic)[hidden]
    assert np.all(excess >= -1e-9)  # never shorter than the true geodesic
    # Longer only by the graph's anisotropy on the part behind the corner, plus the corner's
    # half-cell clearance.
    behind = np.hypot(X - corner[0], Y - corner[1])[hidden]
    assert np.all(excess <= (octile_bound(8) - 1) * behind + 3 * RES)
    # Cells in plain sight keep exact straight-line distances.
    visible = (X > 2.5) & domain.free
    assert np.allclose(g[visible], np.hypot(X - p[0], Y - p[1])[visible], atol=1e-9)


# ---------------------------------------------------------------------------- cells
@pytest.mark.parametrize("seed", range(4))
def test_cells_partition_the_free_space_and_match_the_centralized_tessellation(seed):
    rng = np.random.default_rng(seed)
    domain = random_domain(rng)
    gens = random_generators(domain, rng, 6, weights=seed % 2 == 1)
    central = tessellate(domain, gens)
    owner = np.full(domain.free.size, -1)
    for i, gen in enumerate(gens):
        cell = geodesic_cell(domain, gen, gens[:i] + gens[i + 1:])
        assert np.all(owner[cell.nodes] == -1), "cells overlap"
        owner[cell.nodes] = i
        assert set(cell.nodes.tolist()) == set(np.flatnonzero(central.labels.ravel() == i))
        assert cell.mass == pytest.approx(central.masses[i])
        assert cell.cost == pytest.approx(central.costs[i])
    reachable = np.isfinite(central.distances.ravel()) & domain.free.ravel()
    assert np.array_equal(owner >= 0, reachable)


def test_exact_ties_go_to_one_robot_everywhere():
    """Robots on cell centres, symmetric: many cells are exactly as far from two robots.
    Every robot's own search must give each such cell to the same robot as the others do."""
    domain = empty_domain(30, 40)
    pts = domain.geometry.cell_centers(np.array([[5, 5], [5, 25], [20, 5], [20, 25], [12, 15]]))
    gens = [Generator(p) for p in pts]
    owner = np.full(domain.free.size, -1)
    for i, gen in enumerate(gens):
        cell = geodesic_cell(domain, gen, gens[:i] + gens[i + 1:])
        assert np.all(owner[cell.nodes] == -1), "a tied cell went to two robots"
        owner[cell.nodes] = i
    assert np.all(owner >= 0), "a tied cell went to nobody"
    assert np.array_equal(owner, tessellate(domain, gens).labels.ravel())


@pytest.mark.parametrize("seed", range(3))
def test_fast_update_equals_the_obvious_implementation(seed):
    rng = np.random.default_rng(100 + seed)
    domain = random_domain(rng)
    gens = random_generators(domain, rng, 5, weights=seed == 2)
    for i in range(len(gens)):
        others = gens[:i] + gens[i + 1:]
        fast = geodesic_cell(domain, gens[i], others)
        slow = obvious_cell(domain, gens[i], others)
        order = np.argsort(fast.nodes)
        assert np.array_equal(fast.nodes[order], slow.nodes)
        assert np.allclose(fast.distances[order], slow.distances, atol=1e-9)
        assert fast.mass == pytest.approx(slow.mass) and fast.cost == pytest.approx(slow.cost)
        # Tangent anchors can differ where shortest paths tie; the covectors agree closely.
        assert np.allclose(fast.covector, slow.covector, rtol=0.02,
                           atol=0.02 * np.abs(slow.covector).max())


def test_paper_mode_equals_the_papers_pseudo_code():
    rng = np.random.default_rng(7)
    domain = random_domain(rng)
    gens = random_generators(domain, rng, 5)
    for i in range(len(gens)):
        others = gens[:i] + gens[i + 1:]
        fast = geodesic_cell(domain, gens[i], others, method="paper")
        ref = paper_cell(domain, gens[i], others)
        assert np.array_equal(np.sort(fast.nodes), ref.nodes)
        assert np.allclose(fast.covector, ref.covector, rtol=1e-9, atol=1e-9)
        assert np.allclose(fast.next_vertex, domain.to_map(domain.node_centers(
            np.array([ref.next_vertex])))[0])


def test_cache_and_search_growth_do_not_change_results():
    # Large enough for 24 robots' searches to stay short of the whole map (a search that
    # would cover it all takes the whole-map path, which needs no cache).
    rng = np.random.default_rng(3)
    domain = random_domain(rng, 60, 160, blocks=14)
    gens = random_generators(domain, rng, 24)
    cache = SearchCache()
    for step in range(8):
        gens = [Generator(g.position + rng.normal(0, 0.01, 2)) if domain.is_free_point(
            g.position + 0.0) else g for g in gens]
        gens = [g if domain.is_free_point(g.position) else Generator(g.position) for g in gens]
        cached = geodesic_cell(domain, gens[0], gens[1:], cache=cache)
        fresh = geodesic_cell(domain, gens[0], gens[1:])
        assert np.array_equal(np.sort(cached.nodes), np.sort(fresh.nodes)), step
        assert np.allclose(cached.covector, fresh.covector)
    assert cache.hits > 0
    # A lone robot far from its only neighbour: the first radius is too small and must grow.
    far = geodesic_cell(domain, gens[0], [Generator(gens[0].position + [0.05, 0.0])])
    assert far.passes >= 1
    full = tessellate(domain, [gens[0], Generator(gens[0].position + [0.05, 0.0])])
    assert set(far.nodes.tolist()) == set(np.flatnonzero(full.labels.ravel() == 0))


def test_a_cold_update_starts_from_the_extent_of_its_straight_line_cell():
    """Two robots on an empty 6 m x 4 m map, at (1.5, 2) and (4.5, 2): the first one's cell is
    the left half, which reaches 2.5 m from it (to (0, 0), (0, 4), (3, 0) and (3, 4)). The cold
    radius covers that and exceeds it by at most the sampling gap; the update is one pass."""
    domain = empty_domain(40, 60)
    gens = [Generator(np.array([1.5, 2.0])), Generator(np.array([4.5, 2.0]))]
    centers = domain.to_grid(np.array([g.position for g in gens]))
    L = cold_radius(domain, centers, np.zeros(2))
    gap = math.sqrt(2.0) * COLD_STRIDE * RES
    assert 2.5 <= L <= 2.5 + gap, L
    cell = geodesic_cell(domain, gens[0], gens[1:], cache=SearchCache())
    assert cell.passes == 1 and cell.cell_radius <= L
    # A team bunched in a corner of a larger map: the cell of the robot on the outside is
    # most of the map; it too is found in one pass (a radius from the nearest neighbours took
    # several), and equals the centralized tessellation's.
    domain = empty_domain(80, 120)
    pts = [np.array([0.5 + 0.4 * (k % 3), 0.5 + 0.4 * (k // 3)]) for k in range(6)]
    gens = [Generator(p) for p in pts]
    labels = tessellate(domain, gens).labels.ravel()
    outer = int(np.argmax(np.bincount(labels[labels >= 0])))
    cell = geodesic_cell(domain, gens[outer], gens[:outer] + gens[outer + 1:],
                         cache=SearchCache())
    assert cell.passes == 1
    assert set(cell.nodes.tolist()) == set(np.flatnonzero(labels == outer))


def _wall_scene(length_m: float) -> tuple[CoverageDomain, list[Generator], int]:
    """A wall along y = 2 m from x = 0 to 4.5 m on a ``length_m`` x 6 m map, robots at
    (5.2, 1) right of its end, at (1, 1) below it and at (12, 3); and the map's cell count."""
    occ = np.zeros((60, int(round(length_m / RES))), np.int8)
    occ[20:22, :45] = OCCUPIED
    domain = CoverageDomain.from_grid(GridMap(occ, RES), 0.0)
    gens = [Generator(np.array([5.2, 1.0])), Generator(np.array([1.0, 1.0])),
            Generator(np.array([12.0, 3.0]))]
    return domain, gens, occ.size


def test_a_cell_reaching_round_a_wall_grows_its_search():
    """:func:`_wall_scene` on a 60 m map. The region above the wall's left part is the robot
    at (1, 1)'s in straight lines but the one at (5.2, 1)'s along paths (through the gap): the
    latter's cell reaches further than its straight-line cell, so its cold search is too short
    at first - the second pass searches the whole map (settling what is in line of sight
    first) - and the cell is exact."""
    domain, gens, size = _wall_scene(60.0)
    cell = geodesic_cell(domain, gens[0], gens[1:], cache=SearchCache())
    labels = tessellate(domain, gens).labels.ravel()
    assert cell.passes == 2 and cell.searched_nodes == size
    assert set(cell.nodes.tolist()) == set(np.flatnonzero(labels == 0))
    top_left = domain.to_grid(np.array([[0.3, 5.7]]))[0].astype(int)
    assert labels[top_left[1] * domain.shape[1] + top_left[0]] == 0
    # The paper's pseudo-code sources (no line of sight) grow the pruned search instead.
    paper = geodesic_cell(domain, gens[0], gens[1:], cache=SearchCache(), method="paper")
    assert paper.passes >= 2 and paper.searched_nodes < size
    assert set(paper.nodes.tolist()) == set(np.flatnonzero(
        tessellate(domain, gens, "paper").labels.ravel() == 0))


def test_a_line_of_sight_search_over_a_third_of_the_map_searches_the_whole_map_at_once():
    """:func:`_wall_scene` on a 40 m map: the first search region of the robot at (5.2, 1)
    would hold over a third of the free cells (``SIGHT_WHOLE_SHARE``), so in ``visibility``
    mode it searches the whole map at once (line of sight first; it cannot fall short); in
    ``paper`` mode, whose whole-map search is a plain Dijkstra over every vertex, it searches
    regions up to half the map (``WHOLE_SHARE``) and grows one. Both cells are exact."""
    domain, gens, size = _wall_scene(40.0)
    for method, passes, searched in (("visibility", 1, size), ("paper", 2, None)):
        cell = geodesic_cell(domain, gens[0], gens[1:], cache=SearchCache(), method=method)
        assert cell.passes == passes, method
        assert (cell.searched_nodes == size) if searched else (
            SIGHT_WHOLE_SHARE * size < cell.searched_nodes < WHOLE_SHARE * size), method
        labels = tessellate(domain, gens, method).labels.ravel()
        assert set(cell.nodes.tolist()) == set(np.flatnonzero(labels == 0)), method


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_whole_domain_search_shared_by_a_team_gives_each_robot_its_own_cell(seed):
    """whole=True (one memoized multi-source search per domain and generator set, as an
    exploring team in one process uses it) gives every robot the cell and control of the
    pruned search, also on a curved metric."""
    rng = np.random.default_rng(seed)
    base = random_domain(rng, 40, 50)
    zeta = rng.uniform(0.1, 0.7, base.shape)
    domain = CoverageDomain.from_grid(base.geometry, 0.0, zeta=zeta)
    gens = random_generators(domain, rng, 5)
    for k in range(len(gens)):
        own, others = gens[k], gens[:k] + gens[k + 1:]
        shared = geodesic_cell(domain, own, others, whole=True)
        alone = geodesic_cell(domain, own, others)
        assert np.array_equal(np.sort(shared.nodes), np.sort(alone.nodes)), k
        np.testing.assert_allclose(shared.covector, alone.covector, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(shared.goal, alone.goal)
        assert shared.neighbours == alone.neighbours
    held = domain._cache["shared_search"]  # the one search kept served the five robots
    assert len(held.positions) == len(gens)


@pytest.mark.parametrize("seed", [0, 1])
def test_power_cells_from_searches_kept_in_the_domain_are_the_fresh_ones(seed):
    """With power weights, whole=True keeps each generator's search in the domain
    (:mod:`coverage_ros.core.geodesic.power_rows`): a team in one process that hears the same
    generators, and a robot that updates again without a move, get the cell and control a
    fresh domain gives; a generator that moved is searched again."""
    rng = np.random.default_rng(seed)
    base = random_domain(rng, 40, 50)
    zeta = rng.uniform(0.1, 0.7, base.shape)
    make = lambda: CoverageDomain.from_grid(base.geometry, 0.0, zeta=zeta)  # noqa: E731
    domain = make()
    gens = random_generators(domain, rng, 4, weights=True)
    assert np.ptp([g.weight for g in gens]) > 0

    def check(gens):
        for k in range(len(gens)):
            own, others = gens[k], gens[:k] + gens[k + 1:]
            kept = geodesic_cell(domain, own, others, whole=True)
            fresh = geodesic_cell(make(), own, others, whole=True)
            assert np.array_equal(kept.nodes, fresh.nodes), k
            np.testing.assert_array_equal(kept.distances, fresh.distances)
            np.testing.assert_array_equal(kept.covector, fresh.covector)
            np.testing.assert_array_equal(kept.goal, fresh.goal)
            assert kept.neighbours == fresh.neighbours
        return len(domain._cache["power_rows"])

    assert check(gens) == len(gens)  # one search per generator served the team
    assert check(gens) == len(gens)
    moved = [Generator(random_generators(domain, rng, 1)[0].position, gens[0].weight),
             *gens[1:]]
    assert check(moved) == len(gens) + 1


def test_larger_power_weight_gets_a_larger_cell():
    domain = empty_domain(30, 60)
    a, b = np.array([2.0, 1.5]), np.array([4.0, 1.5])
    masses = []
    weights = (0.0, 0.7, 1.0)
    for r in weights:
        cells = tessellate(domain, [Generator(a, r), Generator(b, 0.0)])
        masses.append(cells.masses[0])
        assert cells.masses.sum() == pytest.approx(domain.mass_element.sum())
    assert masses[0] == pytest.approx(9.0)  # half of the 6 m x 3 m room
    assert masses[0] < masses[1] < masses[2]
    # The power bisector moves by (R_a^2 - R_b^2) / (2 |a - b|) towards b; the room is 3 m high.
    for r, m in zip(weights, masses, strict=True):
        shift = r * r / (2 * 2.0)
        assert m - masses[0] == pytest.approx(shift * 3.0, abs=RES * 3.0)


def test_control_points_to_the_centroid_in_a_convex_room():
    domain = empty_domain(40, 40)
    own = Generator(np.array([0.7, 0.9]))
    cell = geodesic_cell(domain, own, [Generator(np.array([3.2, 3.1]))])
    xy = domain.to_map(domain.node_centers(cell.nodes))
    centroid = xy.mean(axis=0)
    assert np.allclose(cell.goal, centroid, atol=1e-9)
    assert np.allclose(cell.control, centroid - own.position, atol=1e-9)
    step = cell.next_vertex - domain.to_map(domain.node_centers(
        domain.snap(own.position)[0][:1]))[0]
    assert step @ (centroid - own.position) > 0  # the paper's next vertex heads there too


def test_goal_is_clipped_to_reachable_free_space():
    domain = l_domain()
    own = Generator(np.array([3.05, 2.2]))  # right of the bar; most of its cell is behind it
    cell = geodesic_cell(domain, own, [Generator(np.array([3.5, 0.4]))])
    g = domain.to_grid(cell.goal)[0]
    t = np.linspace(0, 1, 200)[:, None]
    line = domain.to_grid(own.position)[0] + t * (g - domain.to_grid(own.position)[0])
    assert all(domain.free[int(y), int(x)] for x, y in line)


# ---------------------------------------------------------------------------- team behaviour
@pytest.mark.slow
@pytest.mark.parametrize("world", ["l_shape", "u_shape"])
def test_coverage_cost_never_increases(world):
    """Generalized Lloyd's steps (the closet escape off: a relocation is a jump its bound
    backs, not a descent step) never raise H, and settle."""
    from coverage_ros.core.offline.runner import OfflineConfig, run_offline
    from coverage_ros.core.strategies import strategy_choice

    # At 10 cm: the world's own 5 cm grid settles the same way in four times the time.
    data = yaml.safe_load((WORLDS / f"{world}.yaml").read_text())
    data["resolution"] = 0.1
    spec = parse_world(data, source=f"{world}.yaml")
    domain = CoverageDomain.from_grid(spec.grid, 0.105, spec.density)
    finals = []
    for seed in (0, 2):
        starts = cluster_starts(spec.grid, 4, 0.105, np.random.default_rng(seed))
        result = run_offline(domain, strategy_choice("geodesic", {"escape": False}), starts,
                             config=OfflineConfig(max_iterations=60))
        H = np.array([tessellate(domain, [Generator(p) for p in P]).cost
                      for P in result.positions])
        assert np.all(np.diff(H) <= 1e-9 * H[0]), np.diff(H).max()
        assert result.converged
        assert H[-1] < 0.15 * H[0]
        finals.append(H[-1])
    # Different clustered starts settle in the same (one arm each) configuration.
    assert finals[0] == pytest.approx(finals[1], rel=0.01)


@pytest.mark.slow
def test_converges_to_lloyds_cvt_in_an_obstacle_free_square():
    """Without the closet escape the geodesic strategy is Lloyd's where every line is a geodesic;
    with it (the default) it ends at Lloyd's CVT or at a lower H."""
    from coverage_ros.core.offline.runner import OfflineConfig, run_offline
    from coverage_ros.core.strategies import StrategyContext, strategy_choice

    domain = CoverageDomain.from_grid(GridMap(np.zeros((80, 80), np.int8), 0.05), 0.0)
    for k, seed in ((4, 0), (5, 1)):
        starts = np.random.default_rng(seed).uniform(0.5, 1.5, (k, 2))
        ctx = [StrategyContext(domain=domain, robot_id=i, convergence_tolerance=0.005)
               for i in range(k)]
        final, H = {}, {}
        for name, choice in (("geodesic", strategy_choice("geodesic", {"escape": False})),
                             ("escape", "geodesic"), ("lloyd", "lloyd")):
            res = run_offline(domain, choice, starts, contexts=ctx,
                              config=OfflineConfig(max_iterations=200))
            assert res.converged
            final[name], H[name] = res.positions[-1], res.costs[-1]
        gap = np.hypot(*(final["geodesic"] - final["lloyd"]).T).max()
        assert gap <= 0.05, f"{k} robots: {gap / 0.05:.2f} cells apart"
        assert H["escape"] <= H["lloyd"] * (1 + 1e-6)


def _sphere_xyz(theta_phi: np.ndarray) -> np.ndarray:
    th, ph = np.asarray(theta_phi, dtype=np.float64).T
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=1)


def test_sphere_four_robots_reach_the_regular_tetrahedron():
    """Four robots on the unit sphere (Bhattacharya et al.'s sphere chart) end where the centroidal
    configuration is known: a regular tetrahedron, four cells of equal area pi."""
    from coverage_ros.core.geodesic.charts import sphere_domain
    from coverage_ros.core.offline.runner import OfflineConfig, run_offline
    from coverage_ros.core.strategies import StrategyContext

    domain = sphere_domain(48)
    starts = np.array([[0.9, 0.5], [1.0, 0.6], [0.95, 0.7], [1.1, 0.55]])  # (theta, phi)
    ctx = [StrategyContext(domain=domain, robot_id=i, convergence_tolerance=0.01)
           for i in range(4)]
    res = run_offline(domain, "geodesic", starts, contexts=ctx,
                      config=OfflineConfig(max_iterations=200))
    final = tessellate(domain, [Generator(p) for p in res.positions[-1]])
    assert final.masses.sum() == pytest.approx(4 * np.pi, rel=0.01)
    # The same cost as tetrahedra in random orientations on the same grid (which differ from
    # each other by ~0.5 % through the grid alone); the start clusters cost 5x more.
    rng = np.random.default_rng(0)
    tetra = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) / np.sqrt(3)
    best = []
    for _ in range(5):
        xyz = tetra @ np.linalg.qr(rng.normal(size=(3, 3)))[0].T
        tp = np.stack([np.arccos(xyz[:, 2]), np.arctan2(xyz[:, 1], xyz[:, 0]) % (2 * np.pi)], 1)
        best.append(tessellate(domain, [Generator(p) for p in tp]).cost)
    assert res.costs[0] > 4 * max(best)
    assert final.cost <= 1.01 * np.mean(best)
    xyz = _sphere_xyz(res.positions[-1])
    angles = np.degrees(np.arccos(np.clip(xyz @ xyz.T, -1, 1)))[np.triu_indices(4, 1)]
    assert np.abs(angles - np.degrees(np.arccos(-1 / 3))).max() < 10
    assert np.abs(final.masses / final.masses.mean() - 1).max() < 0.06
    # Equal areas on the sphere (area element sin(theta) dtheta dphi), not in the chart: which
    # of the two differ more depends on the tetrahedron's orientation.
    inside = final.labels >= 0
    theta = (np.arange(domain.shape[1]) + 0.5) * domain.resolution  # (columns: colatitude)
    element = np.broadcast_to(np.sin(theta) * domain.resolution ** 2, domain.shape)
    sphere = np.bincount(final.labels[inside], weights=element[inside], minlength=4)
    assert final.masses == pytest.approx(sphere, rel=1e-6)


def test_torus_cells_cross_the_chart_seam():
    from coverage_ros.core.geodesic.charts import torus_domain

    domain = torus_domain(48, obstacles=((2.0, 2.0, 2.6, 3.2),))
    period = 2 * math.pi
    gens = [Generator(np.array([0.1, 3.0])), Generator(np.array([3.1, 3.0])),
            Generator(np.array([1.5, 0.2]))]
    central = tessellate(domain, gens)
    for i in range(3):
        cell = geodesic_cell(domain, gens[i], gens[:i] + gens[i + 1:])
        assert set(cell.nodes.tolist()) == set(np.flatnonzero(central.labels.ravel() == i))
    cols = np.flatnonzero(central.labels.ravel() == 0) % domain.shape[1]
    res = domain.resolution
    assert (cols * res < 0.5).any() and ((cols + 1) * res > period - 0.5).any()


def test_vectorized_snap_equals_snap_point_by_point():
    domain = l_domain()
    pts = np.random.default_rng(0).uniform(-0.2, 4.2, (2000, 2))  # some off the map, on walls
    for p, (nodes, costs, g) in zip(pts, domain.snap_many(pts), strict=True):
        nodes1, costs1, g1 = domain.snap(p)
        np.testing.assert_array_equal(nodes, nodes1)
        np.testing.assert_allclose(costs, costs1, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(g, g1)


def _depth_bin_by_bin(origin: np.ndarray, blocked_xy: np.ndarray, bins: int) -> np.ndarray:
    """The polar depth map written the obvious way: every bin of every disc's run, one disc
    at a time."""
    depth = np.full(bins, np.inf)
    step = 2.0 * math.pi / bins
    d = blocked_xy - origin  # (each disc's distance and bearing as numpy rounds them)
    dist = np.hypot(d[:, 0], d[:, 1])
    theta = np.arctan2(d[:, 1], d[:, 0])
    half = np.arcsin(np.minimum(1.0, math.sqrt(0.5) / np.maximum(dist, 1e-9)))
    for r, t, h in zip(dist, theta, half, strict=True):
        for b in range(math.floor((t - h + math.pi) / step),
                       math.floor((t + h + math.pi) / step) + 1):
            depth[b % bins] = min(depth[b % bins], max(r - math.sqrt(0.5), 0.0))
    return depth


def test_the_polar_depth_map_is_the_least_over_every_disc_bin_by_bin(monkeypatch):
    """Runs written as power-of-two blocks give the minima of writing every bin: discs near
    and far (runs from one bin to half a turn), runs across the angle -pi, origins on cell
    centres and corners; runs written bin by bin or as blocks."""
    from coverage_ros.core.geodesic import tangents
    rng = np.random.default_rng(5)
    for trial in range(40):
        bins = (256, 1024, 2048)[trial % 3]
        occ = rng.integers(0, 60, (int(rng.integers(1, 300)), 2)) + 0.5
        origin = rng.uniform(0, 60, 2)
        if trial % 4 == 0:
            origin = np.floor(origin) + (0.5 if trial % 8 else 0.0)
        occ[0] = np.floor(origin) + [-0.5, 0.5]  # (one disc over the origin: half a turn)
        occ = occ.astype(float)
        expected = _depth_bin_by_bin(origin, occ, bins)
        for blocks_from in (0, 5, 10**9):  # (every run by blocks, either way, bin by bin)
            monkeypatch.setattr(tangents, "BLOCKS_FROM", blocks_from)
            np.testing.assert_array_equal(polar_depth(origin, occ, bins), expected)
    assert np.isinf(polar_depth(np.zeros(2), np.zeros((0, 2)), 64)).all()


def test_a_depth_map_kept_for_a_larger_radius_answers_a_smaller_one_alike():
    domain = world_domain(load_world(WORLDS / "office.yaml"), 0.105)
    rng = np.random.default_rng(3)
    H, W = domain.shape
    free = np.argwhere(domain.free)[:, ::-1] + 0.5
    answers = []
    for origin in free[rng.choice(len(free), 6, replace=False)]:
        pts = rng.uniform([0, 0], [W, H], (3000, 2))
        dist = np.hypot(*(pts - origin).T)
        depths: dict = {}
        domain.visible_mask(origin, pts, float(np.hypot(H, W)), depths)  # the whole domain
        for radius in (5.0, 20.0, 60.0):
            near = pts[dist <= radius]
            fresh = domain.visible_mask(origin, near, radius)
            kept = domain.visible_mask(origin, near, radius, depths)
            np.testing.assert_array_equal(kept, fresh)
            answers.append(fresh)
        assert len(depths) == 1  # the whole-domain map served every smaller radius
        small: dict = {}  # and one made for a small radius is not used for a larger one
        domain.visible_mask(origin, pts[dist <= 5.0], 5.0, small)
        far = pts[dist <= 60.0]
        np.testing.assert_array_equal(domain.visible_mask(origin, far, 60.0, small),
                                      domain.visible_mask(origin, far, 60.0))
    answers = np.concatenate(answers)
    assert answers.any() and not answers.all()  # walls hide some points, not all


def test_line_of_sight_decided_by_tiles_equals_the_test_point_by_point():
    """sight_tiles decides whole tiles (seen, hidden) and leaves the rest to visible_from; the
    answers must be visible_from's for every point: cell centres, random points, points on tile
    edges and corners, outside the grid, and origins on tile corners, edges and cell centres."""
    rng = np.random.default_rng(11)
    H, W = 130, 170
    yy, xx = np.mgrid[0:H, 0:W]
    centres = np.stack([xx.ravel() + 0.5, yy.ravel() + 0.5], axis=-1)
    decided = []
    for trial in range(60):
        blocked = rng.random((H, W)) < (0.002, 0.01, 0.05)[trial % 3]
        rr, cc = np.nonzero(blocked)
        occ = np.stack([cc + 0.5, rr + 0.5], axis=-1).astype(float)
        origin = rng.uniform([0, 0], [W, H])
        if trial % 4 == 0:
            origin = np.round(origin / SIGHT_TILE) * SIGHT_TILE
        elif trial % 4 == 1:
            origin = np.floor(origin) + 0.5
        depth = polar_depth(origin, occ, 2048)
        pts = np.concatenate([centres, rng.uniform([-5, -5], [W + 5, H + 5], (4000, 2)),
                              np.round(rng.uniform([0, 0], [W, H], (2000, 2)) / SIGHT_TILE)
                              * SIGHT_TILE])
        states = sight_tiles(origin, depth, (H, W))
        tiled = visible_from(origin, pts, depth, (states, tile_index(pts, (H, W))))
        np.testing.assert_array_equal(tiled, visible_from(origin, pts, depth))
        decided.append(np.mean(states >= 0))
    assert 0.3 < np.mean(decided) < 1.0  # the tiles decide much, not all


def test_the_whole_domain_search_gives_each_robots_cell_with_tiles_as_without(monkeypatch):
    """The visible-first search with line of sight decided by tiles settles the same cells as
    with every point tested alone (the tiles switched off)."""
    from coverage_ros.core.geodesic import sight
    world = load_world(WORLDS / "office.yaml")
    starts = cluster_starts(world.grid, 6, 0.105, np.random.default_rng(1))
    gens = [Generator(p) for p in starts[:, :2]]
    calls = []
    plain = sight.LineOfSight.sight_tiles
    monkeypatch.setattr(sight.LineOfSight, "sight_tiles",
                        lambda self, *a: calls.append(1) or plain(self, *a))

    def cells(domain):
        return [np.sort(geodesic_cell(domain, g, [h for h in gens if h is not g]).nodes)
                for g in gens]

    tiled = cells(world_domain(world, 0.105))
    assert calls  # the whole-domain search ran and used the tiles
    monkeypatch.setattr(sight, "TILED_FROM", 10**12)
    monkeypatch.setattr(sight.LineOfSight, "sight_tiles",  # every tile to be tested
                        lambda self, *a: np.full(len(plain(self, *a)), -1, dtype=np.int8))
    for a, b in zip(tiled, cells(world_domain(world, 0.105)), strict=True):
        np.testing.assert_array_equal(a, b)
