"""Exploring strategies on a belief: Eq. 9's metric, the Lloyd and greedy modes of Bhattacharya
et al. (2014, Sec. 4.2), the nearest-vertex variant, the explore_lite frontier baseline, and
short offline explorations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coverage_ros.core.exploration.belief import Belief, BeliefConfig, entropy
from coverage_ros.core.exploration.maps import EntropyMetric, entropy_domain, trinary_grid
from coverage_ros.core.exploration.sensor_model import ScanCells
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.exploration import ExplorationConfig, run_exploration
from coverage_ros.core.strategies import (
    Neighbour,
    Observation,
    SharedState,
    StrategyContext,
    make_strategy,
    strategy_choice,
)
from coverage_ros.core.strategies.frontier.frontiers import find_frontiers
from coverage_ros.core.world import cluster_starts, parse_world
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError

RES = 0.05


def corridor(explored_cols: tuple[int, int], h: int = 20, w: int = 120) -> Belief:
    """A belief of a 1 m wide corridor (walls on rows 0 and h - 1) explored between the given
    columns, unknown elsewhere."""
    lattice = GridMap(np.full((h, w), -1, np.int8), RES)
    belief = Belief(lattice, 0)
    R, C = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    seen = ((C >= explored_cols[0]) & (C < explored_cols[1])).ravel()
    wall = ((R == 0) | (R == h - 1)).ravel()
    for _ in range(10):
        belief.add_scan(ScanCells(np.flatnonzero(seen & ~wall), np.flatnonzero(seen & wall)))
    return belief


def explorer(belief: Belief, variant: str = "paper", robot_id: int = 0):
    domain = CoverageDomain.from_grid(belief.lattice, 0.105, unknown_is_free=True)
    choice = strategy_choice("geodesic", {"variant": variant}, explore=True)
    return make_strategy(choice, StrategyContext(domain=domain, robot_id=robot_id))


def test_eq9_density_and_metric_on_a_hand_case():
    metric = EntropyMetric(tau=0.5, eps_w=0.01, eps_zeta=0.1)
    e = np.array([0.0, 0.2, 0.49, 0.5, 0.69])
    w, zeta = metric.weights(e)
    np.testing.assert_allclose(w, [0.01, 0.01, 0.01, 0.5, 0.69])
    np.testing.assert_allclose(zeta, [0.1, 0.1, 0.1, 0.5, 0.69])
    # On a belief: an explored cell and an unknown one get those weights, and an edge between
    # two unknown cells is sqrt(zeta) times as long as in the plain metric.
    belief = corridor((0, 60))
    domain, ent = entropy_domain(belief.snapshot(), 0.0, metric)
    assert ent[10, 100] == pytest.approx(math.log(2.0))
    assert domain.density[10, 100] == pytest.approx(math.log(2.0))
    assert domain.density[10, 30] == pytest.approx(0.01)
    assert domain.zeta[10, 30] == pytest.approx(0.1)
    k = next(i for i, (dr, dc) in enumerate(domain.graph.offsets) if (dr, dc) == (0, 1))
    assert domain.graph.cost[10, 100, k] == pytest.approx(RES * math.sqrt(math.log(2.0)))
    assert domain.graph.cost[10, 30, k] == pytest.approx(RES * math.sqrt(0.1))
    with pytest.raises(ConfigError, match="eps_w"):
        EntropyMetric(tau=0.3, eps_w=0.4)


def test_greedy_switch_when_two_unknown_regions_pull_equally():
    """In the middle of a corridor explored in its middle, the two unknown ends pull equally:
    the Lloyd control vanishes while the cell holds unexplored mass, so the robot turns
    greedy and heads for the closest unexplored vertex."""
    belief = corridor((20, 100))
    robot = explorer(belief)
    d = robot.update(Observation(0, np.array([3.0, 0.5, 0.0]), 0.0, None, belief.snapshot()), [])
    assert np.hypot(*(d.details.lloyd_goal - [3.0, 0.5])) < 0.15
    assert d.details.unexplored_mass > 0 and d.mode == "greedy" and d.shared.extra["greedy"] == 1
    assert d.goal[0] == pytest.approx(0.975, abs=0.06) or d.goal[0] == pytest.approx(5.025,
                                                                                      abs=0.06)
    assert entropy(belief.snapshot().probability)[10, int(d.goal[0] / RES)] >= 0.55
    # The target is kept while it stays unexplored and reachable...
    again = robot.update(Observation(0, np.array([2.6, 0.5, 0.0]), 0.5, None,
                                     belief.snapshot()), [])
    np.testing.assert_allclose(again.goal, d.goal)
    # ... and given up once it is explored: back to Lloyd on a now one-sided pull.
    seen = np.flatnonzero((np.arange(120) < 20)[None, :].repeat(20, 0).ravel())
    for _ in range(10):
        belief.add_scan(ScanCells(seen, np.zeros(0, np.int64)))
    after = robot.update(Observation(0, np.array([2.6, 0.5, 0.0]), 1.0, None,
                                     belief.snapshot()), [])
    assert after.mode == "lloyd" and after.goal[0] > 2.6 + 0.1  # pulled to the unknown right


def test_a_one_sided_pull_is_a_lloyd_step_towards_the_unknown():
    belief = corridor((0, 80))
    d = explorer(belief).update(Observation(0, np.array([2.0, 0.5, 0.0]), 0.0, None,
                                            belief.snapshot()), [])
    assert d.mode == "lloyd" and d.goal[0] > 2.5


def test_nearest_variant_splits_the_unknown_between_neighbours():
    """Two robots in the explored middle: each heads for the unknown end on its own side."""
    belief = corridor((20, 100))
    snap = belief.snapshot()
    left, right = np.array([2.0, 0.5, 0.0]), np.array([4.0, 0.5, 0.0])
    a = explorer(belief, "nearest", 0).update(
        Observation(0, left, 0.0, None, snap), [Neighbour(1, SharedState(right[:2]))])
    b = explorer(belief, "nearest", 1).update(
        Observation(1, right, 0.0, None, snap), [Neighbour(0, SharedState(left[:2]))])
    assert a.mode == b.mode == "frontier"
    assert a.goal[0] < 1.05 and b.goal[0] > 4.95


def test_a_target_that_never_gets_explored_is_given_up_and_not_chosen_again():
    """A robot next to an unknown pocket its lidar cannot clear (furniture not closed yet, a
    cell under another robot) keeps it as its target for ``give_up_after`` seconds, then gives
    it up and turns to the next unexplored part; the pocket is not chosen again."""
    belief = corridor((10, 120))  # unknown: columns 0..9 (x < 0.5 m), the far end explored
    robot = explorer(belief, "nearest")
    after = robot.params.give_up_after
    pose = np.array([1.0, 0.5, 0.0])
    first = robot.update(Observation(0, pose, 0.0, None, belief.snapshot()), [])
    assert first.mode == "frontier" and first.goal[0] < 0.5
    kept = robot.update(Observation(0, pose, after - 1.0, None, belief.snapshot()), [])
    np.testing.assert_allclose(kept.goal, first.goal)  # not given up early
    gone = robot.update(Observation(0, pose, after + 0.5, None, belief.snapshot()), [])
    assert len(robot.given_up) == 1 and np.allclose(robot.given_up[0], first.goal)
    assert np.hypot(*(gone.goal - first.goal)) > robot.params.ban_radius  # another target
    # Far from a target, time does not count: a robot on its way is never "stuck".
    far = explorer(belief, "nearest")
    for t in (0.0, 100.0, 200.0):
        d = far.update(Observation(0, np.array([5.5, 0.5, 0.0]), t, None, belief.snapshot()), [])
    assert far.given_up == [] and d.goal[0] < 0.5
    with pytest.raises(ConfigError, match="give_up_after"):
        strategy_choice("geodesic", {"give_up_after": 0.0}, explore=True)


@pytest.mark.parametrize("seed", range(4))
def test_the_closest_unexplored_vertex_is_the_whole_searchs_nearest(seed):
    """closest_unexplored searches out to a growing limit: the vertex it picks is the one a
    search of the whole map picks (the nearest along the metric, the first of equals), and
    None where no unexplored vertex can be reached (a room walled off)."""
    from scipy.sparse.csgraph import dijkstra

    from coverage_ros.core.strategies.explore.strategy import closest_unexplored

    rng = np.random.default_rng(seed)
    h, w = 60, 90
    occ = np.zeros((h, w), np.int8)
    for _ in range(12):  # walls and shelves
        r, c = rng.integers(0, h - 4), rng.integers(0, w - 4)
        occ[r:r + rng.integers(1, 30), c:c + rng.integers(1, 4)] = 100
    occ[:, 70] = 100  # a room beyond a wall: reached by nobody on the left
    zeta = rng.uniform(0.2, 1.0, (h, w))
    domain = CoverageDomain.from_grid(GridMap(occ, RES), 0.0, zeta=zeta)
    free = np.argwhere(domain.free[:, :70])
    for _ in range(5):
        e = np.zeros((h, w))
        k = int(rng.integers(1, 40))
        e[rng.integers(0, h, k), rng.integers(0, w, k)] = 1.0
        r, c = free[rng.integers(len(free))]
        p = domain.geometry.cell_centers(np.array([[r, c]]))[0] + rng.uniform(-0.4, 0.4, 2) * RES
        nodes = domain.snap(p)[0]
        d = dijkstra(domain.graph.csr, directed=True, indices=nodes, min_only=True)
        d[~((e >= 0.5) & domain.free).ravel()] = np.inf
        got = closest_unexplored(domain, e, p, 0.5)
        if not np.isfinite(d.min()):
            assert got is None
            continue
        want = domain.to_map(domain.node_centers(np.array([int(np.argmin(d))])))[0]
        assert got is not None and np.array_equal(got, want)
    e = np.zeros((h, w))
    e[30, 80] = 1.0  # only behind the wall
    assert domain.free[30, 80]
    assert closest_unexplored(domain, e, domain.geometry.cell_centers(free[:1])[0], 0.5) is None


def test_frontiers_of_a_room_with_an_open_door():
    """A 2 m x 2 m room seen free with walls around, but for a 1 m door on its right: one
    frontier along the door, centred on it, without the cells next to the jambs that a robot
    of radius 0.105 m cannot stand beside (explore_lite searches the costmap's free cells)."""
    h, w = 60, 80
    lattice = GridMap(np.full((h, w), -1, np.int8), RES)
    belief = Belief(lattice, 0)
    R, C = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    room = (R >= 10) & (R < 50) & (C >= 10) & (C < 50)
    wall = ((R == 9) | (R == 50)) & (C >= 9) & (C <= 50) | ((C == 9) | (C == 50)) & \
        (R >= 9) & (R <= 50)
    door = (C == 50) & (R >= 20) & (R < 40)
    for _ in range(6):
        belief.add_scan(ScanCells(np.flatnonzero((room | door).ravel()),
                                  np.flatnonzero((wall & ~door).ravel())))
    frontiers = find_frontiers(belief.snapshot(), np.array([1.5, 1.5]), 0.105)
    assert len(frontiers) == 1
    f = frontiers[0]
    assert f.size == 16
    np.testing.assert_allclose(f.centroid, [51 * RES + 0.025, 1.5], atol=1e-9)
    assert f.cost == pytest.approx(3.0 * f.min_distance * RES - f.size * RES)
    # Shorter than min_frontier_size: ignored.
    assert find_frontiers(belief.snapshot(), np.array([1.5, 1.5]), 0.105,
                          min_frontier_size=1.5) == []


def test_frontier_baseline_blacklists_a_goal_it_makes_no_progress_on():
    belief = corridor((20, 100), h=40)  # 2 m wide: frontiers longer than 0.75 m
    domain = CoverageDomain.from_grid(belief.lattice, 0.105, unknown_is_free=True)
    robot = make_strategy(strategy_choice("frontier", {"progress_timeout": 10.0}, explore=True),
                          StrategyContext(domain=domain))
    pose = np.array([3.0, 1.0, 0.0])
    first = robot.update(Observation(0, pose, 0.0, None, belief.snapshot()), [])
    assert first.mode == "frontier" and robot.found == 2
    # Standing still: no progress; after the timeout the goal is given up for the other end.
    for t in np.arange(0.5, 16.0, 0.5):
        last = robot.update(Observation(0, pose, float(t), None, belief.snapshot()), [])
    assert len(robot.blacklist) == 1
    assert np.sign(last.goal[0] - 3.0) != np.sign(first.goal[0] - 3.0)


SMALL = {"bounds": [0, 0, 6, 4],
         "obstacles": [{"type": "wall", "from": [3, 0], "to": [3, 2.6], "thickness": 0.1},
                       {"type": "box", "center": [1.5, 3.0], "size": [0.6, 0.4]}]}


@pytest.mark.parametrize("method", ["geodesic:paper", "geodesic:nearest", "frontier"])
def test_two_robots_explore_a_small_world_offline(method):
    world = parse_world(SMALL)
    starts = cluster_starts(world.grid, 2, 0.105, np.random.default_rng(1))
    strategy, _, variant = method.partition(":")
    choice = strategy_choice(strategy, {"variant": variant} if variant else {}, explore=True)
    run = run_exploration(world.grid, choice, starts, [world.robot_spec(i) for i in range(2)],
                          ExplorationConfig(duration=240.0, until_explored=0.95))
    assert run.explored[-1] >= 0.95, run.explored_at
    assert run.collisions == 0 and run.false_free[-1] <= 0.005
    assert run.min_separation >= 2 * 0.105
    # The saved belief is the map the robots found: walls where the true walls are.
    occ = trinary_grid(run.snapshot).occupancy
    truth = world.grid.occupancy
    assert ((occ == 0) & (truth == 100)).sum() <= 0.005 * (truth == 100).sum()


def test_an_exploring_strategy_needs_a_belief_and_explore_mode():
    domain = CoverageDomain.from_grid(GridMap(np.full((10, 10), -1, np.int8), RES), 0.0,
                                      unknown_is_free=True)
    robot = make_strategy(strategy_choice("geodesic", explore=True),
                          StrategyContext(domain=domain))
    with pytest.raises(ConfigError, match="belief"):
        robot.update(Observation(0, np.array([0.2, 0.2, 0.0]), 0.0), [])
    with pytest.raises(ConfigError, match="unknown strategy for exploring"):
        strategy_choice("lloyd", explore=True)
    with pytest.raises(ConfigError, match="variant"):
        strategy_choice("geodesic", {"variant": "fastest"}, explore=True)
    assert BeliefConfig().frozen_log_odds > 0


@pytest.mark.slow
def test_fig19_a_person_holds_one_robot_in_a_room_of_an_unknown_office():
    """Bhattacharya et al., Fig. 19: four robots with different sensor footprints (power
    cells, R = footprint radius) explore an unknown office while a person keeps robot 0 in a
    room. The others explore everything else (the held robot maps its room), nobody collides,
    and the free robot with the larger footprint ends with a larger cell than either free
    robot with the smaller one (the held robot's cell is whatever its room leaves it: 12.7 and
    9.3 in two versions of the exploration, against 2.9 and 22.3 for the small robots). The run
    of 140 s: 99 % explored at 116 s, the cells in that order at its end (and at 160 and 170 s
    of a longer run)."""
    from conftest import WORLDS

    from coverage_ros.core.geodesic.tessellation import Generator, tessellate
    from coverage_ros.core.world import load_world
    from coverage_ros.core.world.robot import RobotSpec

    world = load_world(WORLDS / "office.yaml")
    specs = [RobotSpec(sensor_radius=s, power_weight=s) for s in (2.0, 2.0, 1.0, 1.0)]
    starts = np.array([[3.0, 2.4, 0.0], [5.0, 4.0, 0.0], [5.5, 4.0, 0.0], [6.0, 4.0, 0.0]])
    run = run_exploration(world.grid, strategy_choice("geodesic", explore=True), starts, specs,
                          ExplorationConfig(duration=140.0), held=[0])
    print(f"\nFig. 19 setting: 95 % at {run.explored_at['0.95']} s, final positions "
          f"{np.round(run.positions[-1], 2).tolist()}")
    assert run.explored[-1] >= 0.99 and run.collisions == 0
    assert np.allclose(run.positions[:, 0], starts[0, :2])  # the person kept robot 0 there
    final = run.positions[-1]
    cells = tessellate(world_domain(world, 0.105),
                       [Generator(final[i], specs[i].power_weight) for i in range(4)])
    print(f"power cell masses: {np.round(cells.masses, 1).tolist()}")
    assert cells.masses[1] > max(cells.masses[2:]) and cells.masses[0] > 0


def test_a_given_up_pocket_inside_furniture_is_banned_whole_and_stops_pulling():
    """The inside of a table whose outline the lidar left open is one small unexplored
    pocket: giving up its first target bans all of it, after which the robot is back in the
    Lloyd mode and its goal is no longer pulled toward the table. A real frontier (a pocket
    larger than ``ban_pocket_area``) only loses the vertices within ``ban_radius`` of the
    target."""
    h, w = 60, 80  # a 3 m x 4 m room, all seen free but a 0.8 m table
    lattice = GridMap(np.full((h, w), -1, np.int8), RES)
    belief = Belief(lattice, 0)
    R, C = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    wall = (R == 0) | (R == h - 1) | (C == 0) | (C == w - 1)
    table = (R >= 20) & (R < 36) & (C >= 50) & (C < 66)
    outline = table & ~((R > 20) & (R < 35) & (C > 50) & (C < 65))
    gap = outline & (C == 50) & (R >= 24) & (R < 32)  # seen free: the outline's hole
    occupied = (wall | outline) & ~gap
    free = ~wall & ~table | gap
    for _ in range(10):
        belief.add_scan(ScanCells(np.flatnonzero(free), np.flatnonzero(occupied)))
    robot = explorer(belief, "nearest")
    pose = np.array([2.0, 1.3, 0.0])
    first = robot.update(Observation(0, pose, 0.0, None, belief.snapshot()), [])
    assert first.mode == "frontier" and 2.5 < first.goal[0] < 3.3  # into the table
    pulled = first.details.lloyd_goal
    gone = robot.update(Observation(0, pose, robot.params.give_up_after + 1.0, None,
                                    belief.snapshot()), [])
    inside = table & ~outline
    assert robot.banned is not None and robot.banned[inside].all()
    assert not robot.banned[~table].any()
    assert gone.mode == "lloyd"
    said = robot.describe()  # the robot log's end-of-run line
    assert len(said) == 1 and f"{int(robot.banned.sum())} vertices (its pocket)" in said[0]
    # From the next update the table is an obstacle for this robot: its Lloyd goal, pulled
    # toward the table's inside before, is back on the room's side away from the table.
    then = robot.update(Observation(0, pose, robot.params.give_up_after + 1.5, None,
                                    belief.snapshot()), [])
    room_centre = np.array([(w / 2) * RES, (h / 2) * RES])
    assert pulled[0] > room_centre[0] + 0.5
    assert then.mode == "lloyd" and then.goal[0] < room_centre[0]
    assert not robot._domain(belief.snapshot())[0].free[inside].any()
    # A frontier into a large unknown: only a ban_radius disc goes.
    big = corridor((100, 200), w=200)  # 5 m x 0.9 m unknown at x < 5 m
    far = explorer(big, "nearest")
    at = np.array([5.5, 0.5, 0.0])
    t0 = far.update(Observation(0, at, 0.0, None, big.snapshot()), [])
    far.update(Observation(0, at, far.params.give_up_after + 1.0, None, big.snapshot()), [])
    assert len(far.given_up) == 1 and "pocket" not in far.describe()[0]
    assert 0 < far.banned.sum() * RES ** 2 < math.pi * far.params.ban_radius ** 2 * 2.5
    assert far.target is not None and far.target[0] < 5.0  # still the same unknown
    assert np.hypot(*(far.target - t0.goal)) > far.params.ban_radius
