"""The geodesic strategy's closet escape (handover): on a small ward with dead-end rooms plain
generalized Lloyd from a start cluster leaves robots shut in small rooms; with the escape the
team ends within 5 % of the best of random restarts, never above plain Lloyd, on free space;
the bound is an upper bound of the true change of H at the configuration it names; claims go
one robot to a cell; a robot's claim depends only on its neighbourhood and the offers it
hears."""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Sequence
from functools import cache

import numpy as np
import pytest

from coverage_ros.core.geodesic.cell import geodesic_cell
from coverage_ros.core.geodesic.tessellation import Generator, fast_tessellate
from coverage_ros.core.geodesic.whole_map import nearest
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.runner import OfflineConfig, run_offline
from coverage_ros.core.strategies import (
    Neighbour,
    Observation,
    StrategyContext,
    make_strategy,
    strategy_choice,
)
from coverage_ros.core.strategies.base import SharedState
from coverage_ros.core.strategies.geodesic import GeodesicParams, GeodesicStrategy
from coverage_ros.core.strategies.handover import (
    joint_change,
    known_cells,
    removal_increase,
    room_offers,
    split_offer,
    split_offers,
)
from coverage_ros.core.strategies.handover.places import HeardMove, Places
from coverage_ros.core.strategies.handover.protocol import STILL_UPDATES, Departure, Handover
from coverage_ros.core.strategies.handover.published import held
from coverage_ros.core.strategies.handover.split import split_parts
from coverage_ros.core.strategies.handover.stillness import TeamStillness
from coverage_ros.core.world import parse_world
from coverage_ros.core.world.placement import largest_free_region, team_starts
from coverage_ros.errors import ConfigError

ROBOTS = 6
RESTARTS = 8
TOLERANCE = 0.02  # [m] coverage-plan's convergence tolerance


def _wall(a, b):
    return {"type": "wall", "from": list(a), "to": list(b), "thickness": 0.1}


#: 10 m x 6 m: a 1 m corridor at y 2.5-3.5, rooms of 4 and 2 m below and 5, 2 and 3 m above,
#: each with one 0.8 m door; the 2 m rooms are dead ends of 5 m^2.
WARD = {"name": "mini_ward", "resolution": 0.1, "bounds": [0.0, 0.0, 10.0, 6.0], "obstacles": [
    _wall((0.0, 2.5), (1.5, 2.5)), _wall((2.3, 2.5), (4.6, 2.5)), _wall((5.4, 2.5), (8.0, 2.5)),
    _wall((8.8, 2.5), (10.0, 2.5)), _wall((0.0, 3.5), (2.5, 3.5)), _wall((3.3, 3.5), (5.6, 3.5)),
    _wall((6.4, 3.5), (8.2, 3.5)), _wall((9.0, 3.5), (10.0, 3.5)), _wall((4.0, 0.0), (4.0, 2.5)),
    _wall((6.0, 0.0), (6.0, 2.5)), _wall((5.0, 3.5), (5.0, 6.0)), _wall((7.0, 3.5), (7.0, 6.0))]}


@cache
def ward():
    world = parse_world(WARD)
    return world, world_domain(world, world.robot_spec(0).radius)


def run(starts: np.ndarray, escape: bool, **settings):
    _, domain = ward()
    contexts = [StrategyContext(domain=domain, robot_id=i, convergence_tolerance=TOLERANCE)
                for i in range(len(starts))]
    choice = strategy_choice("geodesic", {"escape": escape, **settings})
    return run_offline(domain, choice, starts, contexts, OfflineConfig(max_iterations=300))


def cost(positions: np.ndarray) -> tuple[float, np.ndarray]:
    tess = fast_tessellate(ward()[1], [Generator(p) for p in positions])
    return tess.cost, tess.masses


@cache
def two_wards():
    """The ward and a copy of it 10 m to the east, their corridors joined: 20 m x 6 m."""
    shifted = [{**o, "from": [o["from"][0] + 10.0, o["from"][1]],
                "to": [o["to"][0] + 10.0, o["to"][1]]} for o in WARD["obstacles"]]
    world = parse_world({**WARD, "name": "two_wards", "bounds": [0.0, 0.0, 20.0, 6.0],
                         "obstacles": WARD["obstacles"] + shifted})
    return world_domain(world, world.robot_spec(0).radius)


@cache
def best_of_restarts() -> float:
    """The least H of plain Lloyd from RESTARTS random starts over the free space."""
    world, _ = ward()
    rng = np.random.default_rng(7)
    cells = np.argwhere(largest_free_region(world.grid, world.robot_spec(0).radius))
    best = math.inf
    for _ in range(RESTARTS):
        starts = world.grid.cell_centers(cells[rng.choice(len(cells), ROBOTS, replace=False)])
        best = min(best, cost(run(starts, escape=False).positions[-1])[0])
    return best


def cluster(seed: int) -> np.ndarray:
    world, _ = ward()
    return team_starts(world, [world.robot_spec(i) for i in range(ROBOTS)], None, seed)


@cache
def escaped_run(seed: int, rings: int):
    """The run with the escape from ``cluster(seed)`` (kept: two tests look at it)."""
    return run(cluster(seed), escape=True, escape_joint_rings=rings)


@pytest.mark.slow
@pytest.mark.parametrize("rings", [1, 2])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_escape_ends_near_the_best_where_plain_lloyd_is_shut_in(seed, rings):
    best = best_of_restarts()
    plain = run(cluster(seed), escape=False)
    escaped = escaped_run(seed, rings)
    H_plain, m_plain = cost(plain.positions[-1])
    H_escape, _ = cost(escaped.positions[-1])
    # plain Lloyd converges with a robot in a small room: its cell a fraction of the largest
    assert plain.converged and H_plain > 1.05 * best
    assert m_plain.min() < 0.35 * m_plain.max()
    assert escaped.converged
    assert H_escape <= 1.05 * best
    assert H_escape <= H_plain
    assert sum(d.details.relocations for d in escaped.decisions) >= 1
    # no robot ever leaves the free space
    _, domain = ward()
    assert all(domain.is_free_point(p) for p in escaped.positions.reshape(-1, 2))


@pytest.mark.slow
def test_escape_is_deterministic():
    rings = GeodesicParams().escape_joint_rings
    again = run(cluster(2), escape=True)
    assert np.array_equal(again.positions, escaped_run(2, rings).positions)


def _cells(positions: np.ndarray):
    _, domain = ward()
    gens = [Generator(p) for p in positions]
    return [geodesic_cell(domain, gens[i], gens[:i] + gens[i + 1:]) for i in range(len(gens))]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bound_is_above_the_true_change_of_H(seed):
    """For every pair (i leaves, j splits) of plain Lloyd's end state: i at j's offered point
    and i's movable neighbours where the removal put them change H by no more than
    removal_increase(i) - split_gain(j); with no step of the neighbours, so does i's move
    alone."""
    _, domain = ward()
    P = run(cluster(seed), escape=False).positions[-1]
    H0 = cost(P)[0]
    cells = _cells(P)
    offers = [split_offer(domain, c.nodes, c.distances, c.cost, 0.0, c.cell_radius, 3)
              for c in cells]
    checked = 0
    for i, ci in enumerate(cells):
        ids = [k for k in range(len(P)) if k != i]
        gens = np.vstack([P[i][None], P[ids]])
        bordering = [1 + ids.index(ids[k]) for k in ci.neighbours]
        for j, offer in enumerate(offers):
            if j == i or offer is None:
                continue
            fixed = [1 + ids.index(j)] if 1 + ids.index(j) in bordering else []
            for steps in (0, 3):
                removal = removal_increase(domain, gens, 0.0, bordering, fixed,
                                           ci.cell_radius, steps)
                if not math.isfinite(removal.increase):
                    continue
                moved = P.copy()
                moved[i] = offer.point
                for k, p in zip(removal.movers, removal.positions, strict=True):
                    moved[ids[k - 1]] = p
                assert cost(moved)[0] - H0 <= removal.increase - offer.gain + 1e-9 * H0
                checked += 1
    assert checked >= len(P)


@pytest.mark.slow
@pytest.mark.parametrize("rings", [1, 2])
@pytest.mark.parametrize("seed", [0, 2])
def test_joint_bound_is_above_the_true_change_of_H(seed, rings):
    """For every pair (i moves into j's cell at j's offered point) of plain Lloyd's end state:
    the team where the joint bound puts i and the re-spreading neighbours (one or two rings of
    cells around the pair) changes H by no more than the bound, which compares with the
    neighbours' steps without the move."""
    _, domain = ward()
    P = run(cluster(seed), escape=False).positions[-1]
    H0 = cost(P)[0]
    cells = _cells(P)
    offers = [split_offer(domain, c.nodes, c.distances, c.cost, 0.0, c.cell_radius, 3)
              for c in cells]
    checked = paying = 0
    for i in range(len(P)):
        ids = [k for k in range(len(P)) if k != i]
        known = known_cells(domain, np.vstack([P[i][None], P[ids]]))
        for j, offer in enumerate(offers):
            if j == i or offer is None:
                continue
            joint = joint_change(domain, known, 0.0, 1 + ids.index(j), offer.point, 3,
                                 rings=rings)
            if not math.isfinite(joint.increase):
                continue
            moved = _moved(P, i, ids, joint)
            assert cost(moved)[0] - H0 <= joint.increase + 1e-9 * H0
            checked += 1
            paying += joint.increase < 0
    assert checked >= len(P) and paying >= 1


def _lloyd_all_sources(domain, U, movers, fixed, steps, limit):
    """The bound's Lloyd steps in U as written: every step one search from all generators."""
    w = domain.mass_element.ravel()[U]
    rows_, cols_ = np.divmod(U, domain.shape[1])
    pts = domain.to_map(np.column_stack([cols_ + 0.5, rows_ + 0.5]))
    pos, best, at = movers.copy(), math.inf, movers.copy()
    for _ in range(steps + 1):
        g, lab = nearest(domain, np.vstack([pos, fixed]), limit)
        g, lab = g[U], lab[U]
        if not np.all(np.isfinite(g)):
            break
        value = float((g * g * w).sum())
        if value < best:
            best, at = value, pos.copy()
        last = pos.copy()
        for k in range(len(pos)):
            part = lab == k
            if w[part].sum() > 0:
                c = (pts[part] * w[part, None]).sum(axis=0) / w[part].sum()
                pos[k] = pts[part][int(np.argmin(np.hypot(*(pts[part] - c).T)))]
        if np.array_equal(pos, last):
            break
    return best, at


@pytest.mark.parametrize("limit", [math.inf, 2.5])
def test_the_bounds_lloyd_steps_search_the_movers_alone_with_the_same_result(limit):
    """The fixed generators searched once and the movers alone at each step (the nearest of
    all is the nearer of the two) give the cost and positions of searching from all."""
    from coverage_ros.core.strategies.handover.bounds import _lloyd_in

    _, domain = ward()
    P = run(cluster(0), escape=False).positions[-1]
    known = known_cells(domain, P)
    for group in ([0, 1, 2], [3, 5], list(range(len(P)))):
        U = np.flatnonzero(np.isin(known.labels, group))
        movers = P[group] + np.array([0.3, -0.2])  # off their centroids: Lloyd moves them
        movers = np.array([m if domain.is_free_point(m) else p
                           for m, p in zip(movers, P[group], strict=True)])
        fixed = P[[k for k in range(len(P)) if k not in group]]
        want = _lloyd_all_sources(domain, U, movers, fixed, 6, limit)
        got = _lloyd_in(domain, U, movers, fixed, 0.0, 6, limit, "auto")
        assert got[0] == want[0]
        np.testing.assert_array_equal(got[1], want[1])


def _moved(P, i, ids, change):
    """The team at ``P`` with the movers of a bound's ``change`` where it puts them: robot
    ``i`` is generator 0 (mover -1: it, moved), ``ids`` the others in generator order."""
    moved = P.copy()
    for k, p in zip(change.movers, change.positions, strict=True):
        moved[i if k == -1 else ids[k - 1]] = p
    return moved


def _round(strategies, positions, published):
    """One lock-step round: every robot updates from what the others published last."""
    decisions = []
    for i, s in enumerate(strategies):
        obs = Observation(i, np.array([*positions[i], 0.0]), 0.0)
        nbrs = [Neighbour(j, dataclasses.replace(published[j], position=positions[j]))
                for j in range(len(positions)) if j != i]
        decisions.append(s.update(obs, nbrs))
    return decisions


def _claims(domain, P, params: dict, heard: Sequence[HeardMove] = ()
            ) -> list[tuple[int, int, np.ndarray | None, float]]:
    """(robot, robot whose cell it claims, its point, the claim's saving) of every claim a team
    with ``params`` standing at ``P`` makes in the rounds it takes to settle and price, each
    robot having heard the moves ``heard``."""
    team = [make_strategy(strategy_choice("geodesic", params),
                          StrategyContext(domain=domain, robot_id=k,
                                          convergence_tolerance=TOLERANCE))
            for k in range(len(P))]
    for s in team:
        s.handover._moves = list(heard)
    published = [s.shared_state(Observation(k, np.array([*P[k], 0.0]), 0.0))
                 for k, s in enumerate(team)]
    made = []
    for _ in range(STILL_UPDATES + 3):
        decisions = _round(team, P, published)
        made += [(k, int(d.shared.extra["claim"]), team[k].handover.target,
                  d.shared.extra["claim_gain"])
                 for k, d in enumerate(decisions) if d.shared.extra["claim"] >= 0]
        published = [d.shared for d in decisions]
    return made


def _team(positions, domain=None):
    domain = ward()[1] if domain is None else domain
    return [make_strategy(strategy_choice("geodesic"),
                          StrategyContext(domain=domain, robot_id=i,
                                          convergence_tolerance=TOLERANCE))
            for i in range(len(positions))]


#: [m] where a team of 8 on drawn plan 6 ended with one offer per robot (start seed 2 of
#: scripts/bench_closets, H 6 % above the best known): robot 1's cell reaches from its room
#: through a doorway into the corridor and the west rooms; its farthest node lies in the east.
PLAN6_TWO_ROOMS = np.array([
    [2.053, 16.725], [4.233, 12.463], [6.233, 6.009], [1.891, 3.223], [1.833, 6.829],
    [6.529, 2.188], [6.578, 16.888], [6.691, 9.134]])


@cache
def _drawn_plan(seed: int):
    """The domain of scripts/bench_closets' drawn plan ``seed`` on its raster."""
    from coverage_ros.bench.closet_maps import RESOLUTION, coarse_world, drawn_plan

    world = coarse_world(parse_world(drawn_plan(seed)), RESOLUTION)
    return world_domain(world, world.robot_spec(0).radius)


@pytest.mark.parametrize("plan", ["ward", "plan-6"])
def test_splits_searched_to_the_cells_farthest_node_are_the_whole_maps(plan):
    """A split's second generator searched only as far as the cell's farthest node from the
    own generator gives every start's cost, point and part exactly as searched over the whole
    map, on plain Lloyd's end state of the ward (one robot's cell across doorways) and on the
    two-rooms configuration of drawn plan 6."""
    if plan == "ward":
        domain, P = ward()[1], run(cluster(1), escape=False).positions[-1]
    else:
        domain, P = _drawn_plan(6), PLAN6_TWO_ROOMS
    gens = [Generator(p) for p in P]
    compared = 0
    for k, g in enumerate(gens):
        c = geodesic_cell(domain, g, gens[:k] + gens[k + 1:])
        near, whole = (split_parts(domain, c.nodes, c.distances, 0.0, c.cell_radius, 3,
                                   "auto", 4, limit=limit) for limit in (None, math.inf))
        assert len(near) == len(whole) >= 1, k
        for a, b in zip(near, whole, strict=True):
            assert a.cost == b.cost and a.at == b.at, k
            assert np.array_equal(a.point, b.point) and np.array_equal(a.part, b.part), k
            compared += 1
    assert compared >= 2 * len(P)


def test_a_cell_spanning_two_rooms_offers_its_split_in_either():
    """Robot 1's cell offers the farthest-node split (split_offer's, east) and a second one
    in the part that split leaves it (west), which saves more; a generator added at either
    point lowers the team's H by at least the offer's gain (a split is one assignment of the
    cell's nodes, the tessellation the best); the other cells, one room each, offer one split,
    the farthest node's. Claimants price both: the team's first claim goes to the second."""
    domain = _drawn_plan(6)
    P = PLAN6_TWO_ROOMS
    gens = [Generator(p) for p in P]
    H0 = fast_tessellate(domain, gens).cost
    cells = [geodesic_cell(domain, g, gens[:k] + gens[k + 1:]) for k, g in enumerate(gens)]
    for k, c in enumerate(cells):
        offers = split_offers(domain, c.nodes, c.distances, c.cost, 0.0, c.cell_radius, 3)
        first = split_offer(domain, c.nodes, c.distances, c.cost, 0.0, c.cell_radius, 3)
        assert first is not None
        assert offers[0].gain == first.gain and np.array_equal(offers[0].point, first.point)
        assert len(offers) == (2 if k == 1 else 1), k
        for o in offers:
            added = fast_tessellate(domain, gens + [Generator(o.point)]).cost
            assert added <= H0 - o.gain + 1e-9 * H0, k
    east, west = split_offers(domain, cells[1].nodes, cells[1].distances, cells[1].cost, 0.0,
                              cells[1].cell_radius, 3)
    assert west.gain > 1.3 * east.gain and west.point[0] < P[1][0] < east.point[0]

    team = _team(P, domain)
    published = [s.shared_state(Observation(k, np.array([*P[k], 0.0]), 0.0))
                 for k, s in enumerate(team)]
    for _ in range(STILL_UPDATES + 3):
        decisions = _round(team, P, published)
        published = [d.shared for d in decisions]
        claims = [(k, d.shared.extra["claim"]) for k, d in enumerate(decisions)
                  if d.shared.extra["claim"] >= 0]
        if claims:
            break
    assert claims and all(c == 1.0 for _, c in claims)
    assert published[1].extra["offer2_x"] == pytest.approx(west.point[0])
    for k, _ in claims:
        assert np.allclose(team[k].handover.target, west.point), k


#: [m] where a team of 8 on the warehouse map (shared/maps) ended with the pair and the one-ring
#: bounds (start seed 0 of scripts/bench_closets): robots 5 and 7 share a corner, 5's only
#: bordering neighbour is 7, and robot 2's cell across the map is the costliest but one.
WAREHOUSE_CORNER = np.array([
    [10.35, 16.324], [-3.186, 12.559], [-4.286, -21.864], [10.477, -16.697], [-9.279, -2.89],
    [-12.608, 16.001], [5.615, -1.336], [-1.666, 22.872]])


def test_a_robot_in_a_corner_escapes_by_the_wider_ring():
    """Robot 5 leaving its corner for robot 2's cell pays only once the whole team shifts
    along: neither the pair's bound nor the joint one with the cells around the two re-spread
    says so, the one with the next ring of cells does - by more than the escape's margin, at a
    configuration that much lower where every robot stays in its cell or takes 5's."""
    from conftest import shared_map

    from coverage_ros.bench.closet_maps import coarse_world
    from coverage_ros.core.world import load_world

    world = coarse_world(load_world(shared_map("warehouse")), 0.2)
    domain = world_domain(world, world.robot_spec(0).radius)
    P, (i, j) = WAREHOUSE_CORNER, (5, 2)
    H0 = fast_tessellate(domain, [Generator(p) for p in P]).cost
    gens = [Generator(p) for p in P]
    cells = [geodesic_cell(domain, gens[k], gens[:k] + gens[k + 1:]) for k in range(len(P))]
    offer = split_offer(domain, cells[j].nodes, cells[j].distances, cells[j].cost, 0.0,
                        cells[j].cell_radius, 3)
    ids = [k for k in range(len(P)) if k != i]
    own = np.vstack([P[i][None], P[ids]])
    assert [ids[k] for k in cells[i].neighbours] == [7]
    removal = removal_increase(domain, own, 0.0, [1 + ids.index(7)], [], cells[i].cell_radius,
                               3)
    assert removal.increase - offer.gain > 0
    known = known_cells(domain, own)
    one = joint_change(domain, known, 0.0, 1 + ids.index(j), offer.point, 10, rings=1)
    two = joint_change(domain, known, 0.0, 1 + ids.index(j), offer.point, 10, rings=2)
    assert one.increase > 0
    margin = GeodesicParams().escape_gain * (cells[i].cost + cells[j].cost)
    assert two.increase < -margin
    moved = _moved(P, i, ids, two)
    assert fast_tessellate(domain, [Generator(p) for p in moved]).cost - H0 \
        <= two.increase + 1e-9 * H0
    assert set(two.movers) == set(range(1, len(P))) | {-1}  # the whole team shifts


#: [m] a team of 8 on the hostel floor plan (scripts/bench_closets, live, start seed 1) after
#: robot 3 moved into the middle room above the corridor: robot 6 sits in the room below it,
#: robot 1 in the corridor's west end serves the north-west room.
HOSTEL_SETTLED = np.array([
    [10.0, 4.83], [1.29, 4.03], [14.04, 6.67], [7.97, 7.1], [4.05, 2.68], [4.59, 7.05],
    [6.97, 1.92], [13.76, 2.0]])


def test_a_wider_rings_move_counts_where_the_teams_own_descent_goes():
    """Robot 6 moving into robot 1's cell (the north-west room): the wider ring's bound finds
    a configuration lower than staying by Euclidean centroid steps (robot 3 through two
    doorways into the room 6 left), but the robots' own generalized Lloyd steps from the move
    keep 3 in its room and end higher: the move is priced at that (refused), and the team
    that makes it offline (plain Lloyd, every robot's own update) ends as high."""
    from coverage_ros.bench.closet_maps import hostel_plan
    from coverage_ros.core.strategies.handover.bounds import _lloyd_in, descent_change

    world = parse_world(hostel_plan())
    domain = world_domain(world, world.robot_spec(0).radius)
    P, (i, j) = HOSTEL_SETTLED, (6, 1)
    gens = [Generator(p) for p in P]
    H0 = fast_tessellate(domain, gens).cost
    cell_j = geodesic_cell(domain, gens[j], gens[:j] + gens[j + 1:])
    offer = split_offer(domain, cell_j.nodes, cell_j.distances, cell_j.cost, 0.0,
                        cell_j.cell_radius, 3)
    ids = [k for k in range(len(P)) if k != i]
    known = known_cells(domain, np.vstack([P[i][None], P[ids]]))
    # the bound's own steps: every robot re-spreads, one at the offered point
    U = np.flatnonzero(known.labels >= 0)
    start = np.vstack([known.generators[1:], offer.point[None]])
    stay = _lloyd_in(domain, U, known.generators, np.zeros((0, 2)), 0.0, 10, math.inf,
                     "auto")[0]
    moved, at = _lloyd_in(domain, U, start, np.zeros((0, 2)), 0.0, 10, math.inf, "auto")
    assert moved < stay  # a lower configuration exists ...
    k3 = ids.index(3)
    assert at[k3][1] < 4.0 < P[3][1]  # ... with robot 3 in a room below the corridor
    two = joint_change(domain, known, 0.0, 1 + ids.index(j), offer.point, 10, rings=2)
    descent = descent_change(domain, known, 0.0, list(range(1, len(P))), offer.point)
    assert two.increase == descent.increase > 0  # ... which the team's descent misses
    moved_P = _moved(P, i, ids, descent)
    assert fast_tessellate(domain, [Generator(p) for p in moved_P]).cost - H0 \
        <= descent.increase + 1e-9 * H0
    start_P = P.copy()
    start_P[i] = offer.point
    contexts = [StrategyContext(domain=domain, robot_id=k, convergence_tolerance=TOLERANCE)
                for k in range(len(P))]
    plain = run_offline(domain, strategy_choice("geodesic", {"escape": False}), start_P,
                        contexts, OfflineConfig(max_iterations=300))
    H_plain = fast_tessellate(domain, [Generator(p) for p in plain.positions[-1]]).cost
    assert H_plain > H0 + 0.5 * descent.increase  # the robots' own updates end high too


#: [m] a team of 8 on a drawn floor plan (scripts/bench_closets plan-2, start seed 0) where the
#: escape's bounds stopped: robot 7 covers the middle of the corridor and three rooms.
PLAN2_SETTLED = np.array([
    [1.538, 6.998], [10.653, 2.318], [3.87, 6.561], [5.835, 2.199], [1.745, 2.274],
    [13.398, 6.0], [13.854, 2.256], [8.488, 5.382]])


@pytest.mark.slow
def _move_into(domain, P, i: int, j: int):
    """For robot i moving into robot j's cell at the team ``P``: H, every robot's cell, j's
    split offer, the others' ids and the cells robot i knows (generator 0: itself)."""
    gens = [Generator(p) for p in P]
    H0 = fast_tessellate(domain, gens).cost
    cells = [geodesic_cell(domain, g, gens[:k] + gens[k + 1:]) for k, g in enumerate(gens)]
    offer = split_offer(domain, cells[j].nodes, cells[j].distances, cells[j].cost, 0.0,
                        cells[j].cell_radius, 3)
    ids = [k for k in range(len(P)) if k != i]
    return H0, cells, offer, ids, known_cells(domain, np.vstack([P[i][None], P[ids]]))


def test_a_move_no_bound_sees_is_priced_by_the_teams_own_descent():
    """Robot 2 moving to robot 7's offered point: every bound says H rises (the pair's, the
    joint one with one and with two rings re-spreading), but where the team's own generalized
    Lloyd descent goes from the move, every robot descending, H ends lower by more than the
    escape's threshold, and the configuration it names keeps that promise; stopped early once
    it knows, the descent says the same; a team at these positions claims only with offers
    priced so, by the robot whose cell costs least."""
    from coverage_ros.core.strategies.handover.bounds import descent_change

    domain = _drawn_plan(2)
    P, (i, j) = PLAN2_SETTLED, (2, 7)
    H0, cells, offer, ids, known = _move_into(domain, P, i, j)
    threshold = GeodesicParams().escape_gain * (cells[i].cost + offer.base)
    for rings in (1, 2):
        assert joint_change(domain, known, 0.0, 1 + ids.index(j), offer.point, 10,
                            rings=rings).increase > 0, rings
    descent = descent_change(domain, known, 0.0, list(range(1, len(P))), offer.point)
    assert descent.increase < -threshold
    moved = _moved(P, i, ids, descent)
    assert fast_tessellate(domain, [Generator(p) for p in moved]).cost - H0 \
        <= descent.increase + 1e-9 * H0
    # told what is enough, the descent stops early and says the same of the moves robot 1
    # (the least cell) prices (the largest offers), and where it stops keeps its promise
    for i in (1,):
        ids = [k for k in range(len(P)) if k != i]
        known = known_cells(domain, np.vstack([P[i][None], P[ids]]))
        offers = {j: split_offer(domain, cells[j].nodes, cells[j].distances, cells[j].cost,
                                 0.0, cells[j].cell_radius, 3) for j in ids}
        priced = GeodesicParams().escape_descent_offers
        largest = sorted(ids, key=lambda j: -offers[j].gain)[:priced]
        for j in largest:
            offer = offers[j]
            enough = GeodesicParams().escape_gain * (cells[i].cost + offer.base)
            full = descent_change(domain, known, 0.0, list(range(1, len(P))), offer.point)
            short = descent_change(domain, known, 0.0, list(range(1, len(P))), offer.point,
                                   enough=enough)
            assert (short.increase < -enough) == (full.increase < -enough), (i, j)
            assert short.increase >= full.increase - 1e-9 * H0, (i, j)
            moved = _moved(P, i, ids, short)
            assert fast_tessellate(domain, [Generator(p) for p in moved]).cost - H0 \
                <= short.increase + 1e-9 * H0, (i, j)

    assert _claims(domain, P, {"escape_descent_offers": 0}) == []
    # priced by the robot of the least cell only (robot 1: 10 against 23-287)
    assert {k for k, *_ in _claims(domain, P, {"escape_descent_offers": 1})} == {1}



def test_a_move_must_save_a_share_of_the_teams_H():
    """Robot 1's move into robot 7's cell at the plan-2 positions saves S (where the team's
    own descent ends, from the best of the priced starts): claimed while
    ``escape_team_gain`` asks for less than S of the team's H (its descent then goes on past
    the pair's threshold to that share), not once it asks for more - whatever the pair's
    threshold says; asked for half the team's H, nobody claims."""
    from coverage_ros.core.strategies.handover.bounds import descent_change

    domain, P, (i, j) = _drawn_plan(2), PLAN2_SETTLED, (1, 7)
    H0, cells, offer, _, known = _move_into(domain, P, i, j)
    from coverage_ros.core.strategies.handover.pricing import DESCENT_DRAWS, Prices

    shifts = Prices(domain, "auto", 1, 1, 1)
    starts = [known, *(shifts.shifted(known, d) for d in range(1, DESCENT_DRAWS))]
    S = -min(descent_change(domain, k, 0.0, list(range(1, len(P))), offer.point).increase
             for k in starts)
    assert S > GeodesicParams().escape_gain * (cells[i].cost + offer.base)
    params = {"escape_descent_offers": 1, "escape_descent_rooms": 0}
    assert {(k, t) for k, t, *_ in _claims(
        domain, P, params | {"escape_team_gain": 0.9 * S / H0})} == {(i, j)}
    # (a robot whose turn comes after robot 1's may still have a move that saves more)
    assert (i, j) not in {(k, t) for k, t, *_ in _claims(
        domain, P, params | {"escape_team_gain": 1.1 * S / H0})}
    assert _claims(domain, P, params | {"escape_team_gain": 0.5}) == []

#: [m] a live team of 8 on drawn plan 13 within 5 cm of where it ended 5.4 % above the best
#: known (start seed 1 of scripts/bench_closets): robot 0's move to PLAN13_POINT, in robot 4's
#: cell, saves about 62 where robot 7 stays in its room and costs about 95 where it follows
#: into robot 0's old cell, which of the two depending on starts a few cm apart.
PLAN13_NEAR_END = np.array([
    [7.506, 8.041], [18.791, 2.183], [12.375, 8.46], [17.978, 6.099], [2.494, 5.981],
    [4.27, 2.132], [13.68, 4.461], [7.999, 3.408]])
PLAN13_POINT = np.array([4.45, 8.15])


def test_a_move_the_descent_from_the_configuration_heard_misses_is_priced_from_shifted_starts():
    """At PLAN13_NEAR_END the team's own descent from robot 0's move ends 95 higher; from a
    start with every robot shifted by at most half a grid cell it ends 62 lower. A robot
    pricing the move finds the saving, and the price it returns is that descent's."""
    from coverage_ros.core.strategies.handover.bounds import descent_change
    from coverage_ros.core.strategies.handover.pricing import (
        DESCENT_DRAWS,
        JITTER,
        Prices,
        config_key,
    )
    from coverage_ros.core.strategies.handover.published import Offer

    domain, P = _drawn_plan(13), PLAN13_NEAR_END
    known = known_cells(domain, P)
    movers = list(range(1, len(P)))
    single = descent_change(domain, known, 0.0, movers, PLAN13_POINT).increase
    assert single > 50.0
    prices = Prices(domain, "auto", 1, 1, 1)
    shifted = [prices.shifted(known, d) for d in range(1, DESCENT_DRAWS)]
    for k in shifted:  # each start within JITTER of the configuration heard, same robots
        assert np.abs(k.generators - P).max() <= JITTER * domain.resolution + 1e-12
    increases = [descent_change(domain, k, 0.0, movers, PLAN13_POINT).increase
                 for k in shifted]
    assert min(increases) < -50.0
    nbrs = [Neighbour(j, SharedState(position=P[j].copy())) for j in movers]
    offer = Offer((4, 0), 0.0, PLAN13_POINT, 0.0)
    key = config_key(P[0], nbrs)
    price = prices.descent(key, P[0], 0.0, nbrs, offer, 20.0)
    first = next(v for v in increases if v < -20.0)  # drawn until one pays more than 20
    assert price == pytest.approx(
        descent_change(domain, shifted[increases.index(first)], 0.0, movers, PLAN13_POINT,
                       enough=20.0).increase)
    assert price < -20.0



#: [m] a live team of 8 on drawn plan 2 (start seed 0 of scripts/bench_closets) where it stood
#: 10 % above the best known after robot 0's move from here to (6.65, 5.75) was pulled back:
#: robot 3's move to robot 0's second offered point PLAN2_BACK_POINT pays from every start.
PLAN2_PULLED_BACK = np.array([
    [9.389, 5.229], [1.542, 7.014], [6.487, 7.252], [3.873, 6.58], [1.734, 2.32],
    [12.644, 7.163], [14.467, 3.29], [5.836, 2.173]])
PLAN2_BACK_POINT = np.array([8.65, 1.85])


@pytest.mark.parametrize("case", ["plan-2 pulled back", "plan-13 near its end"])
def test_a_move_priced_from_every_start_pays_from_each_of_them(case):
    """Priced from every start (``every``), a move's price is the largest of the descents from
    the configuration heard and its shifted starts, each stopped once it pays, drawn until one
    does not: robot 3's move at PLAN2_PULLED_BACK pays from all five, by their least saving;
    robot 0's move at PLAN13_NEAR_END, which pays from a shifted start only (least of the
    starts), does not."""
    from coverage_ros.core.strategies.handover.bounds import descent_change
    from coverage_ros.core.strategies.handover.pricing import DESCENT_DRAWS, Prices, config_key
    from coverage_ros.core.strategies.handover.published import Offer

    if case == "plan-2 pulled back":
        domain, P, i, point, pays = _drawn_plan(2), PLAN2_PULLED_BACK, 3, PLAN2_BACK_POINT, True
    else:
        domain, P, i, point, pays = _drawn_plan(13), PLAN13_NEAR_END, 0, PLAN13_POINT, False
    enough = 3.0
    known = known_cells(domain, np.vstack([P[i], np.delete(P, i, axis=0)]))
    prices = Prices(domain, "auto", 1, 1, 1)
    starts = [known, *(prices.shifted(known, d) for d in range(1, DESCENT_DRAWS))]
    movers = list(range(1, len(P)))
    increases = []  # (until one does not pay)
    for k in starts:
        increases.append(descent_change(domain, k, 0.0, movers, point, enough=enough).increase)
        if increases[-1] >= -enough:
            break
    nbrs = [Neighbour(j, SharedState(position=P[j].copy())) for j in range(len(P)) if j != i]
    offer = Offer((0, 1), 0.0, point, 0.0)
    key = config_key(P[i], nbrs)
    every = prices.descent(key, P[i], 0.0, nbrs, offer, enough, every=True)
    least = prices.descent(key, P[i], 0.0, nbrs, offer, enough)
    assert least < -enough  # (the least of the starts pays in both cases)
    assert every == pytest.approx(max(increases))
    if pays:
        assert len(increases) == DESCENT_DRAWS and every < -enough
    else:
        assert every >= -enough


#: [m] where a team of 8 on drawn plan 12 ended with no offer paying (start seed 1 of
#: scripts/bench_closets, H 6.5 % above the best known): robot 6 covers from the corridor
#: a west room, the large east room and the south-east room; robot 4 sits in the south-west
#: closet. Robot 6's own splits name the west and south-east rooms.
PLAN12_SETTLED = np.array([
    [1.836, 12.634], [2.28, 6.869], [7.019, 12.991], [3.324, 9.82], [1.674, 1.307],
    [7.026, 8.407], [4.986, 2.77], [4.354, 15.008]])


@pytest.mark.slow
def test_a_cell_over_several_rooms_offers_the_descent_a_point_in_each():
    """At the plan-12 positions no robot's move into the largest offers pays by the team's
    own descent (a team without the room offers claims nothing); the rooms of robot 6's cell
    other than those of its offers each get a point, and robot 4 (the least cell) moving to
    the large east room's lowers H by more than the escape's threshold, where the descent
    names a configuration that keeps the promise. A team at these positions claims only with
    the rooms priced: robot 4, into robot 6's cell, at a point in that room."""
    from coverage_ros.core.strategies.handover.bounds import descent_change

    domain, P = _drawn_plan(12), PLAN12_SETTLED
    gens = [Generator(p) for p in P]
    H0 = fast_tessellate(domain, gens).cost
    cells = [geodesic_cell(domain, g, gens[:k] + gens[k + 1:]) for k, g in enumerate(gens)]
    i, j = 4, 6
    assert min(range(len(P)), key=lambda k: cells[k].cost) == i
    offers = split_offers(domain, cells[j].nodes, cells[j].distances, cells[j].cost, 0.0,
                          cells[j].cell_radius, 3)
    ids = [k for k in range(len(P)) if k != i]
    known = known_cells(domain, np.vstack([P[i][None], P[ids]]))
    taken = np.array([o.point for o in offers])
    rooms = room_offers(domain, cells[j].nodes, cells[j].distances, cells[j].cost, 0.0,
                        cells[j].cell_radius, 3, GeodesicParams().escape_descent_rooms, taken)
    assert rooms and [r.gain for r in rooms] == sorted((r.gain for r in rooms), reverse=True)
    owner = known_cells(domain, P).labels
    W = domain.shape[1]
    for r in rooms:
        col, row = np.floor(domain.to_grid(r.point[None])[0]).astype(int)
        assert owner[row * W + col] == j and 0 < r.gain < cells[j].cost
        assert min(np.hypot(*(taken - r.point).T)) > 2.0  # [m] another room than the offers'
    east = [r for r in rooms if r.point[0] > 5.5 and 2.5 < r.point[1] < 6.0]
    assert len(east) == 1
    enough = GeodesicParams().escape_gain * (cells[i].cost + cells[j].cost)
    descent = descent_change(domain, known, 0.0, list(range(1, len(P))), east[0].point)
    assert descent.increase < -enough
    moved = _moved(P, i, ids, descent)
    assert fast_tessellate(domain, [Generator(p) for p in moved]).cost - H0 \
        <= descent.increase + 1e-9 * H0

    assert _claims(domain, P, {"escape_descent_rooms": 0}) == []
    made = _claims(domain, P, {})
    assert {(k, c) for k, c, *_ in made} == {(i, j)}
    to = made[0][2]
    assert to[0] > 5.5 and 2.5 < to[1] < 6.0


@pytest.mark.slow
def test_a_robot_claims_no_more_where_the_team_came_back_after_its_move():
    """At the plan-2 positions robot 1 claims robot 7's cell (priced by the descent) and
    relocates; if the team comes back to where it left from (its steps need not reach the
    configuration the descent named), or near it (every other robot 0.3 m off, as live robots
    stop) at an H no lower, robot 1 does not claim from there again, where a robot that did
    not move from there claims; from an H lower by more than its move had to save, it claims
    again. The robots that heard the move keep where the team stood: at the same places with
    robot 1 and robot 0 in each other's, robot 0 does not make the move robot 1 made, where a
    robot 0 that never heard it does (a team going round a cycle of moves, each robot once),
    nor does it with the others 0.3 m off; with the places it kept a room away, it does."""
    domain, P = _drawn_plan(2), PLAN2_SETTLED

    def robot(k):
        return make_strategy(strategy_choice("geodesic", {"escape_descent_offers": 1}),
                             StrategyContext(domain=domain, robot_id=k,
                                             convergence_tolerance=TOLERANCE))

    team = [robot(k) for k in range(len(P))]
    published = [s.shared_state(Observation(k, np.array([*P[k], 0.0]), 0.0))
                 for k, s in enumerate(team)]
    heard = target = None
    for _ in range(STILL_UPDATES + 12):
        decisions = _round(team, P, published)
        if heard is None and decisions[1].shared.extra["claim"] >= 0:
            heard = published  # what robot 1 heard when it claimed: all settled, offers out
        published = [d.shared for d in decisions]
        if decisions[1].mode == "relocate":
            target = team[1].handover.target.copy()
            break
    assert heard is not None and target is not None, "robot 1 never relocated"
    arrived = P.copy()
    arrived[1] = target
    published = [d.shared for d in _round(team, arrived, published)]
    assert team[1].handover.cooldown > 0  # arrived: its claim dropped

    def claims(strategy, Q=P, i=1, places=None) -> list[float]:
        """Robot i's claims at Q, hearing what was published from each place (``places[j]``:
        the robot whose published values robot j at Q[j] repeats; the same by default)."""
        places = list(range(len(Q))) if places is None else places
        nbrs = [Neighbour(j, dataclasses.replace(heard[places[j]], position=Q[j]))
                for j in range(len(Q)) if j != i]
        rounds = GeodesicParams().escape_cooldown + STILL_UPDATES + 2
        return [strategy.update(Observation(i, np.array([*Q[i], 0.0]), 0.0), nbrs)
                .shared.extra["claim"] for _ in range(rounds)]

    assert max(claims(team[1])) < 0
    assert max(claims(robot(1))) == 7
    swapped = [1, 0, *range(2, len(P))]  # robot 0 where robot 1 stood and the other way round
    assert max(claims(team[0], P[swapped], 0, swapped)) < 0
    assert max(claims(robot(0), P[swapped], 0, swapped)) == 7
    left = team[1].handover._departures[-1]
    near = P.copy()
    for j in range(len(P)):
        if j != 1:
            near[j] = next(P[j] + d for d in ([0.3, 0.0], [-0.3, 0.0], [0.0, 0.3], [0.0, -0.3])
                           if domain.is_free_point(P[j] + np.array(d)))
    H_near = fast_tessellate(domain, [Generator(p) for p in near]).cost
    assert H_near >= left.cost - left.saving
    assert max(claims(team[1], near)) < 0
    assert max(claims(robot(1), near)) == 7
    assert max(claims(team[0], near[swapped], 0, swapped)) < 0
    kept = team[0].handover._moves[-1]
    assert np.array_equal(kept.start, P[1]) and np.hypot(*(kept.end - target)) < 1e-9
    team[0].handover._moves = [dataclasses.replace(kept, places=dataclasses.replace(
        kept.places, points=kept.places.points + [4.0, 0.0]))]
    assert max(claims(team[0], P[swapped], 0, swapped)) == 7
    team[1].handover._departures = [dataclasses.replace(left, cost=H_near + 2 * left.saving)]
    assert max(claims(team[1], near)) == 7


def test_a_robot_goes_back_once_the_team_settles_above_where_its_move_left_from():
    """Robot 1 of the settled plan-2 team has just moved, from a place in robot 7's cell, out
    of a configuration of H ``cost`` that its move had to lower by ``saving``. Settled again
    above ``cost + saving``, the move did not pay: robot 1 claims robot 7's cell for that
    place, at what going back should save, and once granted drives there - a move it does
    not judge in turn, nor keeps as a departure. Settled within ``cost + saving``, the move
    stands: it claims nothing (no bound sees a move there and the descent is off)."""
    domain, P = _drawn_plan(2), PLAN2_SETTLED
    H = fast_tessellate(domain, [Generator(p) for p in P]).cost
    ids = tuple(k for k in range(len(P)) if k != 1)
    back = next(P[7] + np.array(d) for d in ([0.3, 0.0], [-0.3, 0.0], [0.0, 0.3], [0.0, -0.3])
                if domain.is_free_point(P[7] + np.array(d)))
    saving = 0.01 * H

    def rounds(cost: float):
        team = [make_strategy(strategy_choice("geodesic", {"escape_descent_offers": 0}),
                              StrategyContext(domain=domain, robot_id=k,
                                              convergence_tolerance=TOLERANCE))
                for k in range(len(P))]
        team[1].handover._judging = Departure(ids, cost, saving, (back[0], back[1]))
        published = [s.shared_state(Observation(k, np.array([*P[k], 0.0]), 0.0))
                     for k, s in enumerate(team)]
        seen = []
        for _ in range(STILL_UPDATES + 4):
            decisions = _round(team, P, published)
            d = decisions[1]
            seen.append((int(d.shared.extra["claim"]), d.shared.extra["claim_gain"], d.mode,
                         None if d.goal is None else np.asarray(d.goal)[:2].copy()))
            published = [d.shared for d in decisions]
        return team[1].handover, seen

    mover, seen = rounds(H - 2 * saving)
    claims = [(c, g) for c, g, *_ in seen if c >= 0]
    assert claims and {c for c, _ in claims} == {7}
    assert claims[0][1] == pytest.approx(2 * saving, rel=1e-6)
    going = [goal for *_, mode, goal in seen if mode == "relocate"]
    assert going and np.allclose(going[-1], back)
    assert mover._judging is None and mover._departures == []
    mover, seen = rounds(H - 0.5 * saving)
    assert [c for c, *_ in seen] == [-1] * len(seen)
    assert mover._judging is None


def test_a_move_priced_by_the_descent_where_a_move_heard_left_from_must_save_more():
    """At the plan-2 positions robot 1's move into robot 7's cell is priced by the descent
    (no bound sees it), which stops once the move pays. A team that heard a move leave from
    these same places and stands there again came back from it: the descent was wrong there.
    With the mover back where it left from (robot 5, pulled back) a move priced by the descent
    must pay from every start: robot 1's does, and is claimed at its least saving over them.
    With the mover where it went and the robot it displaced where it left from (robot 7 from
    robot 5's place, the two traded places) a move priced by the descent must save more than
    the heard move's claim - robot 1's descent runs on past 1.5 times its first price, not past
    2.5 times (robot 2's move then pays); a move heard from places a room away changes
    nothing."""
    domain, P = _drawn_plan(2), PLAN2_SETTLED
    params = {"escape_descent_offers": 1, "escape_descent_rooms": 0}
    made = _claims(domain, P, params)
    assert {(k, t) for k, t, *_ in made} == {(1, 7)}
    first = made[0][3]

    def heard(shift: list[float], saving: float, mover: int = 7) -> list[HeardMove]:
        return [HeardMove(Places(tuple(range(len(P))), P + shift), P[5].copy(), P[7].copy(),
                          saving, mover)]

    made = _claims(domain, P, params, heard([0.05, -0.05], 0.0, mover=5))
    assert {(k, t) for k, t, *_ in made} == {(1, 7)}
    assert all(g <= first for *_, g in made)
    # (shifted a little: as live robots stop)
    made = _claims(domain, P, params, heard([0.05, -0.05], 1.5 * first))
    assert {(k, t) for k, t, *_ in made} == {(1, 7)}
    assert all(g > 1.5 * first for *_, g in made)
    made = _claims(domain, P, params, heard([0.0, 0.0], 2.5 * first))
    assert made and (1, 7) not in {(k, t) for k, t, *_ in made}
    assert all(g > 2.5 * first for *_, g in made)
    made = _claims(domain, P, params, heard([4.0, 0.0], 100 * first, mover=5))
    assert {(k, t) for k, t, *_ in made} == {(1, 7)} and made[0][3] == first


def test_places_are_the_same_whichever_robot_stands_where():
    """:class:`~coverage_ros.core.strategies.handover.protocol.Places`: the same robots at the
    same points in another order are the same places, each point off by less than ``near``
    too; one point farther off, or another robot, is not."""
    def places(ids, points):
        return Places(tuple(ids), np.array(points, dtype=np.float64))

    a = places([0, 1, 2], [[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]])
    assert a.same(places([0, 1, 2], [[0.0, 5.0], [0.0, 0.0], [5.0, 0.0]]), 0.1)
    assert a.same(places([0, 1, 2], [[0.0, 5.09], [0.0, 0.0], [5.0, 0.0]]), 0.1)
    assert not a.same(places([0, 1, 2], [[0.0, 5.11], [0.0, 0.0], [5.0, 0.0]]), 0.1)
    assert not a.same(places([0, 1, 3], [[0.0, 5.0], [0.0, 0.0], [5.0, 0.0]]), 0.1)
    assert not a.same(places([0, 1], [[0.0, 5.0], [0.0, 0.0]]), 0.1)
    # a pairing with every pair near, not the nearest place of each (0.4 off each here, two
    # of them nearest to 1.0)
    b = places([0, 1, 2], [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    c = places([0, 1, 2], [[0.6, 0.0], [1.6, 0.0], [1.4, 0.0]])
    assert not b.same(c, 0.45)
    assert b.same(c, 0.61)
    # a move heard from places a: made again from them only by a robot where the mover
    # stood, to where it went; other moves from there stay open
    move = HeardMove(a, np.array([5.0, 0.0]), np.array([9.0, 9.0]))
    here = places([0, 1, 2], [[0.0, 5.0], [0.05, 0.0], [5.0, 0.0]])
    assert move.again(here, np.array([5.0, 0.0]), np.array([9.05, 9.0]), 0.1)
    assert not move.again(here, np.array([5.0, 0.0]), np.array([9.0, 9.2]), 0.1)
    assert not move.again(here, np.array([0.0, 5.0]), np.array([9.0, 9.0]), 0.1)
    assert not move.again(c, np.array([5.0, 0.0]), np.array([9.0, 9.0]), 0.1)
    # its mover (robot 1) back where it left from, or not
    moved = dataclasses.replace(move, mover=1)

    def at(k, point):
        return [Neighbour(k, SharedState(position=np.array(point), weight=0.0))]

    assert moved.pulled_back(at(1, [5.05, 0.0]), 0.1)
    assert not moved.pulled_back(at(1, [9.0, 9.0]), 0.1)
    assert not moved.pulled_back(at(2, [5.0, 0.0]), 0.1)
    assert not move.pulled_back(at(1, [5.0, 0.0]), 0.1)  # (mover not known)


def test_one_claimant_per_cell_and_claims_follow_grants():
    """Robots standing still at plain Lloyd's end: claims and grants round by round; each
    cell lets in at most one robot, a robot relocates only on its target's grant."""
    P = run(cluster(2), escape=False).positions[-1]
    team = _team(P)
    published = [s.shared_state(Observation(i, np.array([*P[i], 0.0]), 0.0))
                 for i, s in enumerate(team)]
    relocated = False
    for _ in range(STILL_UPDATES + 6):
        decisions = _round(team, P, published)
        claims = [int(d.shared.extra["claim"]) for d in decisions]
        grants = [int(d.shared.extra["grant"]) for d in decisions]
        for i, d in enumerate(decisions):
            if d.mode == "relocate":
                relocated = True
                assert int(published[claims[i]].extra["grant"]) == i
        targets = [c for i, c in enumerate(claims) if decisions[i].mode == "relocate"]
        assert len(targets) == len(set(targets))
        for j, g in enumerate(grants):
            if g >= 0:  # a grant answers a claim on the cell (it may be dropped meanwhile)
                assert int(published[g].extra["claim"]) == j and claims[j] < 0
        published = [d.shared for d in decisions]
    assert relocated


def test_a_relocating_robots_neighbours_hold_its_generator_where_it_left_until_it_arrives():
    """A robot on its way publishes its point; while it drives the others' cells keep its
    generator where it stood when they first heard it relocating, so nobody spreads into the
    cell it leaves before it has arrived (the team then descends from the configuration the
    claim priced, the robot at its point, not from one the others reached meanwhile). Once it
    has arrived they take its new position, and standing still so far no longer settles them:
    a robot whose Lloyd step is now long neither offers nor claims."""
    P = run(cluster(2), escape=False).positions[-1]
    team = _team(P)
    domain = ward()[1]
    published = [s.shared_state(Observation(i, np.array([*P[i], 0.0]), 0.0))
                 for i, s in enumerate(team)]
    mover = None
    for _ in range(STILL_UPDATES + 6):
        decisions = _round(team, P, published)
        published = [d.shared for d in decisions]
        mover = next((i for i, d in enumerate(decisions) if d.mode == "relocate"), None)
        if mover is not None:
            break
    assert mover is not None
    goal = np.array(decisions[mover].goal)
    extra = published[mover].extra
    assert extra["relocating"] == 1.0 and (extra["to_x"], extra["to_y"]) == tuple(goal)

    def cells_with(i, at):  # robot i's cell of the team at ``at``
        return geodesic_cell(domain, Generator(at[i], 0.0),
                             [Generator(q, 0.0) for k, q in enumerate(at) if k != i]).nodes

    driving = P.copy()
    for share in (0.0, 0.5):  # first heard where it stood, then half way there
        driving[mover] = P[mover] + share * (goal - P[mover])
        decisions = _round(team, driving, published)
        published = [d.shared for d in decisions]
        assert decisions[mover].mode == "relocate"
        for i, d in enumerate(decisions):
            if i != mover:
                assert np.array_equal(np.sort(d.cell), np.sort(cells_with(i, P))), i
    arrived = P.copy()
    arrived[mover] = goal
    decisions = _round(team, arrived, published)  # it drops its claim; the others still hold
    published = [d.shared for d in decisions]
    assert decisions[mover].mode == "lloyd" and published[mover].extra["relocating"] == 0.0
    decisions = _round(team, arrived, published)
    moving = 0
    for i, d in enumerate(decisions):
        if i == mover:
            continue
        assert np.array_equal(np.sort(d.cell), np.sort(cells_with(i, arrived))), i
        if np.hypot(*(d.goal - arrived[i])) >= GeodesicParams().escape_settle:
            moving += 1  # stood still for updates, but its cell has just changed
            assert d.shared.extra["settled"] == 0.0 and d.shared.extra["claim"] < 0, i
    assert moving >= 1


def test_held_counts_a_relocating_robot_where_it_was_first_heard_and_says_when_it_arrived():
    """:func:`~coverage_ros.core.strategies.handover.published.held`: the first position heard
    with ``relocating`` stands for the whole way; arriving away from it is reported once, and
    arriving where it stood (the offline runner's robots reach their point in one update, so
    the first position heard is the point) is not."""
    def heard(x, relocating):
        return Neighbour(3, SharedState(position=np.array([x, 1.0]), weight=0.0, mass=1.0,
                                        extra={"relocating": relocating, "to_x": 5.0,
                                               "to_y": 1.0}))

    origins: dict = {}
    assert held(heard(1.0, 1.0), origins, 0.1)[0].tolist() == [1.0, 1.0]
    for x in (2.0, 4.9):
        at, arrived = held(heard(x, 1.0), origins, 0.1)
        assert at.tolist() == [1.0, 1.0] and not arrived
    at, arrived = held(heard(5.0, 0.0), origins, 0.1)
    assert at.tolist() == [5.0, 1.0] and arrived and not origins
    assert held(heard(5.0, 0.0), origins, 0.1)[1] is False  # once
    held(heard(5.0, 1.0), origins, 0.1)  # first heard relocating at its point
    assert held(heard(5.0, 0.0), origins, 0.1)[1] is False


def test_standing_still_away_from_the_centroid_settles_only_after_a_while():
    """Robots of the start cluster that have not begun to drive (turning, waiting) are not
    settled, so they neither offer nor claim, until they stood still STILL_UPDATES updates."""
    P = cluster(0)[:, :2]
    team = _team(P)
    published = [s.shared_state(Observation(i, np.array([*P[i], 0.0]), 0.0))
                 for i, s in enumerate(team)]
    for k in range(STILL_UPDATES + 1):
        decisions = _round(team, P, published)
        far = [i for i, d in enumerate(decisions)
               if np.hypot(*(d.goal - P[i])) >= GeodesicParams().escape_settle]
        assert len(far) >= ROBOTS // 2
        for i in far:
            # the first update has no previous position; the k-th has k - 1 still ones before
            assert decisions[i].shared.extra["settled"] == float(k >= STILL_UPDATES), (k, i)
            assert decisions[i].shared.extra["claim"] < 0 or k >= STILL_UPDATES
        published = [d.shared for d in decisions]


def test_the_settle_threshold_is_a_share_of_a_small_cells_radius():
    """escape_settle caps it; on a cell of area pi r^2 it is escape_settle_share * r [m]."""
    s = GeodesicParams(escape_settle=0.1, escape_settle_share=0.04).handover()
    assert s.settle_below(math.pi) == pytest.approx(0.04)  # r = 1 m
    assert s.settle_below(math.pi * 0.25) == pytest.approx(0.02)  # r = 0.5 m
    assert s.settle_below(math.pi * 100.0) == 0.1  # r = 10 m: escape_settle
    assert s.settle_below(0.0) == 0.0


def test_a_step_short_of_escape_settle_on_a_small_cell_does_not_settle():
    """A robot of the start cluster, its first update, its Lloyd goal between the share of its
    cell's radius and escape_settle away: not settled, but settled by escape_settle alone."""
    _, domain = ward()
    P = cluster(0)[:, :2]
    cell = geodesic_cell(domain, Generator(P[0], 0.0), [Generator(q, 0.0) for q in P[1:]])
    below = GeodesicParams().handover().settle_below(len(cell.nodes) * domain.resolution ** 2)
    assert below < GeodesicParams().escape_settle  # a small cell
    step = 0.5 * (below + GeodesicParams().escape_settle)  # [m]
    for share, settled in ((GeodesicParams().escape_settle_share, 0.0), (1.0, 1.0)):
        robot = Handover(0, domain, GeodesicParams(escape_settle_share=share).handover())
        out = robot.step(cell.goal - [step, 0.0], 0.0, cell, [], [], TOLERANCE)
        assert out.extra["settled"] == settled, share


def _two_wards_at_lloyds_end():
    """Two wards side by side, plain Lloyd's end state of the ward in each: the domain, the
    positions, a fresh team there and what it publishes before its first update."""
    domain = two_wards()
    half = run(cluster(2), escape=False).positions[-1]
    P = np.vstack([half, half + [10.0, 0.0]])
    team = _team(P, domain)
    published = [s.shared_state(Observation(i, np.array([*P[i], 0.0]), 0.0))
                 for i, s in enumerate(team)]
    return domain, P, team, published


def test_no_claim_while_another_robot_claims():
    """One move at a time: at plain Lloyd's end (in two wards side by side) robots claim a
    cell, but none does while a robot it hears has a claim out, however small its saving."""
    _, P, team, published = _two_wards_at_lloyds_end()

    def claims(states):  # the next round from the same robots' states
        return [int(d.shared.extra["claim"]) for d in _round(copy.deepcopy(team), P, states)]

    for _ in range(STILL_UPDATES + 4):  # until the next round has a claim
        published = [d.shared for d in _round(team, P, published)]
        free = claims(published)
        if any(c >= 0 for c in free):
            break
    else:
        pytest.fail("nobody claimed a cell")
    quiet, target = 0, 1
    held = list(published)
    held[quiet] = dataclasses.replace(published[quiet], extra={
        **published[quiet].extra, "claim": float(target), "claim_gain": 1e-6})
    assert [c for i, c in enumerate(claims(held)) if i != quiet] == [-1] * (len(P) - 1)


def test_a_robot_cooling_down_is_not_done():
    """Of the claims made at once at Lloyd's end all but one are dropped, and those robots wait
    out their cooldown before they claim again: meanwhile they are not converged and say a
    phase is under way, so a runner does not stop the team before they may move (a drawn
    floor plan's team stopped so 44 % above the best known)."""
    _, P, team, published = _two_wards_at_lloyds_end()
    cooled = set()
    for _ in range(STILL_UPDATES + 4 + GeodesicParams().escape_cooldown):
        decisions = _round(team, P, published)
        for i, (s, d) in enumerate(zip(team, decisions, strict=True)):
            if s.handover.cooldown > 0:
                cooled.add(i)
                assert d.settling and not d.converged, i
        published = [d.shared for d in decisions]
    assert len(cooled) >= 2


def test_a_claim_uses_only_the_neighbourhood_and_the_offers():
    """The robot that claims first makes the same claim, in the same state, from a neighbour
    list cut down to the robot whose offer it takes and the robots whose cells border its own
    or the target's, or theirs (the cells its bounds re-tessellate). Two wards side by side,
    plain Lloyd's end state of the ward in each."""
    domain, P, team, published = _two_wards_at_lloyds_end()
    for _ in range(6):
        before = [dataclasses.replace(s.handover) for s in team]
        decisions = _round(team, P, published)
        claimants = [i for i, d in enumerate(decisions) if d.shared.extra["claim"] >= 0]
        if claimants:
            break
        published = [d.shared for d in decisions]
    else:
        pytest.fail("nobody claimed a cell")
    claimant = claimants[0]
    target = int(decisions[claimant].shared.extra["claim"])
    near = set(decisions[claimant].details.neighbours) \
        | set(decisions[target].details.neighbours) | {target}
    # their cells, which it tessellates from their own neighbours
    second = {j for k in near for j in decisions[k].details.neighbours}
    keep = (near | second) - {claimant}
    assert len(keep) < len(P) - 1  # the cut list leaves robots out
    alone = _team(P, domain)[claimant]
    alone.handover = before[claimant]
    obs = Observation(claimant, np.array([*P[claimant], 0.0]), 0.0)
    nbrs = [Neighbour(j, dataclasses.replace(published[j], position=P[j]))
            for j in sorted(keep)]
    local = alone.update(obs, nbrs)
    assert local.shared.extra["claim"] == target
    assert local.shared.extra["claim_gain"] == pytest.approx(
        decisions[claimant].shared.extra["claim_gain"], rel=1e-9)


def test_update_takes_only_the_observation_and_the_neighbours():
    import inspect

    params = list(inspect.signature(GeodesicStrategy.update).parameters)
    assert params == ["self", "obs", "neighbours"]


@pytest.mark.parametrize("name,value", [
    ("escape", "yes"), ("escape_gain", -0.1), ("escape_gain", math.inf),
    ("escape_team_gain", -0.01),
    ("escape_settle", -1.0), ("escape_settle_share", -0.1), ("escape_settle_share", math.nan),
    ("escape_cooldown", 0), ("escape_wait", 0),
    ("escape_transit", 0), ("escape_steps", 0), ("escape_steps", 1.5),
    ("escape_joint_steps", 0), ("escape_joint_rings", 0), ("escape_joint_rings", 1.5),
    ("escape_descent_offers", -1), ("escape_descent_offers", True),
    ("escape_descent_rooms", -1), ("escape_descent_rooms", 2.0),
    ("escape_still", -1), ("escape_still", 2.5),
    ("escape_descent_step", -0.1), ("escape_descent_step", math.inf)])
def test_settings_are_checked_by_name(name, value):
    with pytest.raises(ConfigError, match=name):
        GeodesicParams(**{name: value})
    with pytest.raises(ConfigError, match=name):
        strategy_choice("geodesic", {name: value})


def test_a_descent_of_short_steps_keeps_a_robot_in_the_room_a_whole_step_leaves():
    """Drawn plan 24, four robots: three along the corridor, one in the bottom middle room
    (where a live team settles from start seed 1). Robot 0 moving from the corridor's west end
    into the room north of robot 1 pays by whole Lloyd steps: the team re-spreads with robot 0
    back in the corridor. By steps of at most 0.11 m (a live robot's reach between updates) it
    stays in the room and H rises, as the live team's did; robot 0 moving into the room south
    of where it stands pays either way."""
    from coverage_ros.core.strategies.handover.bounds import descent_change

    domain = _drawn_plan(24)
    P = np.array([[2.0, 5.06], [6.59, 5.02], [13.51, 4.9], [9.3, 2.17]])
    north, south = np.array([6.05, 8.25]), np.array([2.0, 0.5])
    whole = descent_change(domain, known_cells(domain, P), 0.0, [1, 2, 3], north)
    assert whole.increase < -100.0 and whole.positions[-1][1] < 5.5  # back in the corridor
    short = descent_change(domain, known_cells(domain, P), 0.0, [1, 2, 3], north, max_step=0.11)
    assert short.increase > 50.0 and short.positions[-1][1] > 7.0  # still in the room
    assert descent_change(domain, known_cells(domain, P), 0.0, [1, 2, 3], south,
                          max_step=0.11).increase < -100.0


def test_with_short_descent_steps_a_joint_bound_is_priced_by_the_descent():
    """Drawn plan 24, four robots: robot 0 in the room south of the corridor's west part, the
    others along the corridor (where a live team with short descent steps but bounds taken at
    their word settles from start seed 2). Its move into the room north of the corridor pays by
    the joint bound of one ring (its Euclidean centroid steps take a robot through a doorway);
    the team's descent from it ends higher, by whole steps as by short ones, and with short
    steps the joint bound returns that descent's price."""
    domain = _drawn_plan(24)
    P = np.array([[5.38, 2.42], [14.02, 4.91], [2.03, 5.05], [9.26, 4.88]])
    north = np.array([6.15, 7.65])
    assert joint_change(domain, known_cells(domain, P), 0.0, 3, north, 10).increase < -100.0
    short = joint_change(domain, known_cells(domain, P), 0.0, 3, north, 10, max_step=0.11)
    assert short.increase > 100.0 and short.positions[-1][1] > 7.0  # in the room, H up


def test_without_escape_nothing_extra_is_published():
    P = cluster(0)[:, :2]
    team = [make_strategy(strategy_choice("geodesic", {"escape": False}),
                          StrategyContext(domain=ward()[1], robot_id=i)) for i in range(ROBOTS)]
    published = [s.shared_state(Observation(i, np.array([*P[i], 0.0]), 0.0))
                 for i, s in enumerate(team)]
    for d in _round(team, P, published):
        assert dict(d.shared.extra) == {} and d.mode == "lloyd"


def test_a_robot_dithering_far_from_its_goal_settles_and_one_driving_does_not():
    """A live robot whose goal flips between two rooms turns back and forth in place: moving
    more than the tolerance each update, never nearer its goal, it is settled once its last
    STILL_UPDATES + 1 positions lie within the settle step of their mean; one driving at the
    same pace in one direction is not."""
    _, domain = ward()
    cell = geodesic_cell(domain, Generator(cluster(0)[0, :2], 0.0), [])  # the whole ward
    below = GeodesicParams().handover().settle_below(len(cell.nodes) * domain.resolution ** 2)
    hop = 3.0 * TOLERANCE  # [m] per update, as much back and forth as on the way
    assert hop / 2 < below
    start = cell.goal - [1.0, 0.0]  # [m] a metre short of its goal
    for path, settles in (([start + [hop * (k % 2), 0.0] for k in range(8)], True),
                          ([start + [hop * k, 0.0] for k in range(8)], False)):
        robot = Handover(0, domain, GeodesicParams().handover())
        settled = [robot.step(p, 0.0, cell, [], [], TOLERANCE).extra["settled"] for p in path]
        assert settled == [float(settles and k >= STILL_UPDATES) for k in range(8)], settles


def test_team_stillness_judges_every_robot_heard_over_the_window_by_the_updates_it_is_in():
    """Still: every robot heard at the window's start within the distance of its mean position
    over the keys it is in (dithering back and forth passes, creeping one way at the same pace
    does not; one missed in between or at the latest key is judged by the rest), and no robot
    of the latest key heard only since the start (not known to stand); a window of 0 is always
    still."""
    def key(ids, xy):
        return np.column_stack([ids, np.asarray(xy, dtype=np.float64)])

    ids, base = [-1.0, 2.0, 5.0], np.array([[1.0, 1.0], [3.0, 1.0], [2.0, 4.0]])
    assert TeamStillness(0).still(0.05)
    for moves, still in ((lambda k: [0.0, 0.06 * (k % 2)], True),  # (dithers 6 cm)
                         (lambda k: [0.0, 0.015 * k], False),  # (creeps 1.5 cm per update)
                         (lambda k: [0.0, 0.0], True)):
        team = TeamStillness(10)
        for k in range(11):
            xy = base.copy()
            xy[1] += moves(k)
            team.note(key(ids, xy))
            assert team.still(0.05) == (still and k == 10), k
    team = TeamStillness(3)
    for k in range(4):  # (robot 5 heard only from the second update on)
        team.note(key(ids, base) if k else key(ids[:2], base[:2]))
    assert not team.still(0.05)
    team.note(key(ids, base))
    assert team.still(0.05)
    for k in range(4):  # (robot 5 missed at the second and third: at the edge of its range)
        team.note(key(ids[:2], base[:2]) if k in (1, 2) else key(ids, base))
    assert team.still(0.05)
    moved = base + [[0.0, 0.0], [0.0, 0.0], [0.0, 0.2]]
    for k in range(4):  # (... moved by the latest key, missed once before it)
        team.note(key(ids[:2], base[:2]) if k == 1 else key(ids, moved if k == 3 else base))
    assert not team.still(0.05)
    for k in range(4):  # (moved by the third key, missed at the latest: judged all the same)
        team.note(key(ids[:2], base[:2]) if k == 3 else key(ids, moved if k == 2 else base))
    assert not team.still(0.05)
    for _ in range(4):  # (not heard since the window's start: no longer judged)
        team.note(key(ids[:2], base[:2]))
    assert team.still(0.05)
    team.restart()
    for _ in range(4):
        assert not team.still(0.05)
        team.note(key(ids, base))
    assert team.still(0.05)  # (the window filled again)


def test_with_escape_still_a_robot_claims_only_once_the_team_stands():
    """At plain Lloyd's end in two wards side by side robots claim cells; with a window of
    escape_still updates none claims while a robot they hear creeps 1.5 cm per update (settled
    by its own test, as a live team re-spreading after a move), each busy meanwhile - without
    the window they claim all the same - and once it stands they claim again."""
    domain, P, _, _ = _two_wards_at_lloyds_end()
    window, creeper = 20, len(P) - 1

    def rounds(still: int, creep: int, total: int, busy_from: int = 0) -> list[int]:
        """The round of every claim over ``total`` rounds, robot ``creeper`` creeping for
        the first ``creep`` of them (the others busy from round ``busy_from`` while it
        creeps)."""
        team = [make_strategy(strategy_choice("geodesic", {"escape_still": still}),
                              StrategyContext(domain=domain, robot_id=k,
                                              convergence_tolerance=TOLERANCE))
                for k in range(len(P))]
        published = [s.shared_state(Observation(k, np.array([*P[k], 0.0]), 0.0))
                     for k, s in enumerate(team)]
        at, made = P.copy(), []
        for r in range(total):
            if r < creep:
                at[creeper] = P[creeper] + [0.0, 0.015 * r]
            decisions = _round(team, at, published)
            for k, d in enumerate(decisions):
                if d.shared.extra["claim"] >= 0:
                    made.append(r)
                if still and busy_from <= r < creep and k != creeper:
                    assert d.settling and not d.converged, (r, k)
            published = [d.shared for d in decisions]
            published[creeper] = dataclasses.replace(
                published[creeper], extra={**published[creeper].extra, "settled": 1.0})
        return made

    creep = STILL_UPDATES + 24
    free = rounds(0, creep, creep)  # (no window: claims while it creeps)
    assert free
    assert not rounds(window, creep, creep, busy_from=min(free))
    late = rounds(window, creep, creep + window + STILL_UPDATES + 4, busy_from=min(free))
    assert late and min(late) >= creep
