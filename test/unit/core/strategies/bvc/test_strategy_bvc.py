"""Wang et al. 2024: buffered Voronoi cells from lidar points and the deadlock-aware
guided map - geometry (Lemma 1, Eq. 5-7), the navigation function (Lemma 2), the strategy, its
Table I metrics, a U-shaped trap and the paper's 30 random three-peak trials."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from conftest import WORLDS
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize
from scipy.sparse.csgraph import dijkstra

import coverage_ros.core.strategies.bvc.strategy as bvc_strategy
from coverage_ros.bench.peak_trials import (
    TrialOutcome,
    average_time,
    cluttered_trial,
    coverage_ratio,
    peaks_detected,
    run_trial,
    success_rate,
    table_row,
    world_clearance,
)
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.euclidean import clip_polygon
from coverage_ros.core.geodesic.graph import build_grid_graph
from coverage_ros.core.geometry import distance_to_segments, polygon_area, polygon_edges
from coverage_ros.core.offline.runner import OfflineConfig, run_offline
from coverage_ros.core.strategies import (
    STRATEGIES,
    Neighbour,
    Observation,
    SharedState,
    StrategyContext,
    make_strategy,
    strategy_choice,
)
from coverage_ros.core.strategies.bvc.cells import (
    buffered_cell,
    convex_polygon_cells,
    disc_halfplanes,
    eq6_hyperplane,
    halfplane_polygon,
    spherical_flip,
    visible_points,
)
from coverage_ros.core.strategies.bvc.guided_map import (
    WindowGraph,
    local_map,
    local_maximum_goal,
    navigation_function,
)
from coverage_ros.core.strategies.bvc.memory import ObstacleMemory
from coverage_ros.core.world import (
    LidarSpec,
    RobotSpec,
    clearance,
    cluster_starts,
    load_world,
    parse_world,
)
from coverage_ros.errors import ConfigError

TOL = 1e-7  # [m] floating-point slack of the geometric checks
RADIUS = 0.2  # [m] robot radius of the property tests (larger than a TB3's to stress buffers)
SENSOR = 3.0  # [m] sensing radius of the property tests


# ---------------------------------------------------------------------------- geometry helpers
def _point_polygon_distance(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance from points to a convex counter-clockwise polygon (0 inside)."""
    a, b = polygon_edges(poly)
    d = distance_to_segments(points, a, b)
    e = b - a
    rel = points[:, None, :] - a[None]
    inside = np.all(e[None, :, 0] * rel[..., 1] - e[None, :, 1] * rel[..., 0] >= 0, axis=1)
    return np.where(inside, 0.0, d)


def _polygon_distance(p: np.ndarray, q: np.ndarray) -> float:
    """Distance between two convex polygons (0 if they overlap)."""
    return float(min(_point_polygon_distance(p, q).min(), _point_polygon_distance(q, p).min()))


@st.composite
def scenes(draw):
    """1-4 robots at least 2 r apart and an obstacle cloud (scattered points and densely sampled
    walls, as a lidar returns them) at least r from every robot."""
    n = draw(st.integers(1, 4))
    coords = st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False)
    robots = np.array([[draw(coords), draw(coords)] for _ in range(n)])
    gaps = np.hypot(*(robots[:, None] - robots[None]).transpose(2, 0, 1))
    gaps[np.diag_indices(n)] = np.inf
    if gaps.min() < 2 * RADIUS + 1e-3:
        robots = robots[:1]
    far = st.floats(-4.0, 4.0, allow_nan=False, allow_infinity=False)
    pts = [np.array([[draw(far), draw(far)] for _ in range(draw(st.integers(0, 25)))])]
    for _ in range(draw(st.integers(0, 3))):
        a, b = np.array([draw(far), draw(far)]), np.array([draw(far), draw(far)])
        t = np.linspace(0.0, 1.0, 40)[:, None]
        pts.append(a + t * (b - a))
    cloud = np.vstack([p.reshape(-1, 2) for p in pts])
    d = np.hypot(cloud[:, None, 0] - robots[None, :, 0], cloud[:, None, 1] - robots[None, :, 1])
    return robots, cloud[np.all(d >= RADIUS + 1e-3, axis=1)]


# ---------------------------------------------------------------------------- Eq. 5-7, Lemma 1
def test_spherical_flip_reverses_distances_along_each_ray():
    p = np.array([1.0, -2.0])
    q = p + np.array([[0.5, 0.0], [0.0, 2.0], [-1.0, 1.0]])
    f = spherical_flip(q, p, 3.0)
    d = np.hypot(*(q - p).T)
    assert np.allclose(np.hypot(*f.T), 2 * 3.0 - d)  # |q'| = 2 R - |q - p|
    assert np.allclose(f / np.hypot(*f.T)[:, None], (q - p) / d[:, None])  # same ray


def test_visible_points_drop_the_points_hidden_behind_a_wall():
    y = np.linspace(-1.0, 1.0, 21)
    near = np.stack([np.full_like(y, 1.0), y], axis=-1)
    behind = np.stack([np.full_like(y, 2.0), 0.5 * y], axis=-1)  # fully in the near row's shadow
    pts = np.vstack([near, behind])
    vis = visible_points(pts, np.zeros(2), 3.0)
    assert len(vis) > 0 and np.all(vis < len(near))
    assert 10 in vis  # the nearest point, straight ahead


def test_eq6_closed_form_is_the_qp_optimum():
    rng = np.random.default_rng(6)
    p = np.array([0.3, -0.7])
    for q in p + rng.uniform(-3.0, 3.0, (20, 2)):
        a, b = eq6_hyperplane(q, p)
        d = q - p
        res = minimize(lambda x: x @ x, np.ones(2), jac=lambda x: 2 * x, method="SLSQP",
                       constraints=[{"type": "ineq", "fun": lambda x, d=d: d @ x - 1.0,
                                     "jac": lambda x, d=d: d}],
                       options={"ftol": 1e-12})
        assert res.success, res.message
        assert np.allclose(a, res.x, atol=1e-6)
        assert math.isclose(b, a @ q)  # tight at the point


def test_halfplane_polygon_matches_sutherland_hodgman_clipping():
    rng = np.random.default_rng(7)
    for _ in range(30):
        k = int(rng.integers(1, 12))
        normals = rng.normal(size=(k, 2))
        offsets = rng.uniform(0.1, 2.0, k)  # every half-plane contains the origin
        da, dc = disc_halfplanes(np.zeros(2), 2.5)
        a, c = np.vstack([normals, da]), np.concatenate([offsets, dc])
        fast = halfplane_polygon(a, c, np.zeros(2))
        slow = np.array([[2.5, 0.0], [0.0, 2.5], [-2.5, 0.0], [0.0, -2.5]]) * 2.0
        for n_k, c_k in zip(a, c, strict=True):
            slow = clip_polygon(slow, n_k, c_k)
        assert math.isclose(polygon_area(fast), polygon_area(slow), rel_tol=1e-9)
        assert _point_polygon_distance(slow, fast).max() < 1e-9


def test_halfplane_polygon_finds_an_interior_point_and_reports_empty_regions():
    da, dc = disc_halfplanes(np.zeros(2), 2.0)
    a = np.vstack([[[1.0, 0.0], [-1.0, 0.0]], da])
    square = halfplane_polygon(a, np.concatenate([[0.5, 0.5], dc]), np.array([5.0, 5.0]))
    assert len(square) >= 4 and np.allclose(np.abs(square[:, 0]).max(), 0.5)
    assert len(halfplane_polygon(a, np.concatenate([[-0.5, -0.5], dc]), np.zeros(2))) == 0


def test_convex_polygon_cells_match_a_point_in_polygon_test():
    rng = np.random.default_rng(8)
    rows, cols = np.mgrid[0:20, 0:18]
    centres = np.stack([cols.ravel() + 0.5, rows.ravel() + 0.5], axis=-1)
    for _ in range(40):
        da, dc = disc_halfplanes(np.zeros(2), 9.0)
        poly = halfplane_polygon(np.vstack([rng.normal(size=(6, 2)), da]),
                                 np.concatenate([rng.uniform(2.0, 9.0, 6), dc]),
                                 np.zeros(2)) + rng.uniform(0, 18, 2)
        r, c = convex_polygon_cells(poly, (20, 18))
        got = np.zeros((20, 18), dtype=bool)
        got[r, c] = True
        assert len(r) == got.sum()  # no cell twice
        want = _point_polygon_distance(centres, poly).reshape(20, 18) == 0
        assert np.array_equal(got, want)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenes())
def test_lemma1_cells_are_safe_disjoint_and_buffered(scene):
    robots, cloud = scene
    cells = []
    for i, p in enumerate(robots):
        others = np.delete(robots, i, axis=0)
        cell = buffered_cell(p, cloud, others, RADIUS, SENSOR)
        poly = cell.polygon
        # 1) non-empty, and the robot (collision-free) lies in it
        assert len(poly) >= 3 and polygon_area(poly) > 0
        assert cell.contains(p[None])[0]
        assert cell.buffer == RADIUS
        # 2) inside the Voronoi cell, at least r from every bisector
        for q in others:
            u = (q - p) / np.hypot(*(q - p))
            assert np.all((poly - 0.5 * (p + q)) @ u <= -RADIUS + TOL)
        # 5), 6) every obstacle point - sensed or beyond the sensor - at least r away
        if len(cloud):
            assert _point_polygon_distance(cloud, poly).min() >= RADIUS - TOL
        # within the sensing disc shrunk by r
        assert np.hypot(*(poly - p).T).max() <= SENSOR - RADIUS + TOL
        cells.append(poly)
    # 3), 4) cells of different robots are disjoint and at least r_i + r_j apart
    for i in range(len(cells)):
        for j in range(i + 1, len(cells)):
            assert _polygon_distance(cells[i], cells[j]) >= 2 * RADIUS - TOL


def test_cell_shrinks_its_buffer_instead_of_vanishing_when_too_close():
    y = np.linspace(-2.0, 2.0, 81)
    wall = np.stack([np.full_like(y, 0.1), y], axis=-1)  # 0.1 m < r from the robot
    cell = buffered_cell(np.zeros(2), wall, np.zeros((0, 2)), RADIUS, SENSOR)
    assert 0 < cell.buffer < RADIUS
    assert cell.contains(np.zeros((1, 2)))[0]
    assert _point_polygon_distance(wall, cell.polygon).min() >= cell.buffer - TOL


# ---------------------------------------------------------------------------- Lemma 2, goal
def test_window_graph_distances_equal_the_grid_graph():
    rng = np.random.default_rng(9)
    free = rng.random((31, 31)) > 0.25
    window = WindowGraph(31, 0.1)
    reference = build_grid_graph(free, 0.1, connectivity=8).csr
    for source in (0, 480, 960):
        got = dijkstra(window.csr(free), indices=source)
        got[got > 1e8] = np.inf
        want = dijkstra(reference, indices=source)
        assert np.array_equal(np.isinf(got), np.isinf(want))
        assert np.allclose(got[np.isfinite(got)], want[np.isfinite(want)])


def test_navigation_function_descends_to_the_goal_around_remembered_walls():
    memory = ObstacleMemory.covering((0.0, 0.0, 6.0, 6.0), 0.1)
    memory.add(np.stack([np.full(30, 3.05), np.linspace(1.0, 4.0, 30)], axis=-1))  # a wall
    local = local_map(memory, np.array([2.0, 2.5]), 35, inflation=0.1)
    nf = navigation_function(local, np.array([5.0, 2.5]))
    cost = nf.cost
    # Lemma 2: 0 at the goal, and every other reachable cell has a strictly lower neighbour.
    r, c, _ = local.lookup(np.array([5.0, 2.5]))
    assert cost[r[0], c[0]] == 0.0 and np.sum(cost == 0.0) == 1
    assert nf.at(np.array([5.0, 2.5]))[0] < 0.1 * math.sqrt(2)  # within a cell of the goal
    finite = np.isfinite(cost)
    padded = np.pad(cost, 1, constant_values=np.inf)
    lowest = np.min([padded[1 + dr:cost.shape[0] + 1 + dr, 1 + dc:cost.shape[1] + 1 + dc]
                     for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc], axis=0)
    assert np.all((lowest < cost)[finite & (cost > 0)])
    # The way around the wall is longer than the straight line through it.
    assert nf.at(np.array([2.0, 2.5]))[0] > 3.0 + 0.5
    assert not np.isfinite(nf.at(np.array([3.05, 2.5]))[0])  # on the wall


def test_local_maximum_goal_prefers_high_then_near_and_keeps_its_goal():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    vals = np.array([0.5, 1.0, 0.2, 1.0])
    assert local_maximum_goal(pts, vals, np.array([3.2, 0.0])) == 3  # tie: the nearer
    assert local_maximum_goal(pts, vals, np.array([0.0, 0.0])) == 1
    vals = np.array([0.5, 0.99, 0.2, 1.0])
    assert local_maximum_goal(pts, vals, np.zeros(2), previous=pts[1], match_radius=0.1) == 1
    assert local_maximum_goal(pts, vals, np.zeros(2)) == 3
    assert local_maximum_goal(np.zeros((0, 2)), np.zeros(0), np.zeros(2)) is None


# ---------------------------------------------------------------------------- the strategy
def _open_domain(size: float = 6.0) -> CoverageDomain:
    spec = parse_world({"name": "open", "resolution": 0.1, "bounds": [0, 0, size, size],
                        "density": {"type": "gaussian_mixture",
                                    "components": [{"mean": [4.5, 3.0], "sigma": 0.7}]}})
    return CoverageDomain.from_grid(spec.grid, 0.105, spec.density)


def test_registered_and_validated():
    assert STRATEGIES["bvc"].needs_scan
    ctx = StrategyContext(domain=_open_domain())
    choice = strategy_choice("bvc", {"gamma": 3.0, "guided": False})
    assert make_strategy(choice, ctx).params.gamma == 3.0
    for bad, where in (({"gama": 1.0}, "unknown parameters"), ({"gamma": -1.0}, "bvc.gamma"),
                       ({"guided": "yes"}, "bvc.guided"), ({"u_max": 0.0}, "bvc.u_max"),
                       ({"grid_resolution": math.nan}, "bvc.grid_resolution"),
                       ({"nf_radius": 1.0}, "bvc.nf_radius"),
                       ({"bridge_width": -0.1}, "bvc.bridge_width")):
        with pytest.raises(ConfigError, match=where):
            make_strategy(strategy_choice("bvc", bad), ctx)


def test_decision_moves_towards_the_density_inside_the_own_cell():
    domain = _open_domain()
    robot = make_strategy("bvc", StrategyContext(domain=domain,
                                                 robot=RobotSpec(sensor_radius=3.5)))
    pose = np.array([1.0, 3.0, 0.0])
    stay = robot.update(Observation(0, pose, 0.0, None), [])
    assert np.allclose(stay.goal, pose[:2]) and not stay.converged
    from coverage_ros.core.offline.rangesim import simulate_scan

    scan = simulate_scan(domain.geometry, pose, LidarSpec())
    d = robot.update(Observation(0, pose, 0.2, scan), [])
    assert d.mode == "guided"
    assert np.allclose(d.details.guide_goal, [4.5, 3.0], atol=0.1)
    assert _point_polygon_distance(d.goal[None], d.cell_polygon)[0] == 0.0  # goal in the cell
    assert d.goal[0] > pose[0] + 1.0  # towards the peak
    assert np.hypot(*d.details.u) == pytest.approx(robot.u_max)  # saturated (Eq. 3)
    assert len(d.cell) > 0 and d.mass > 0


def test_a_neighbour_is_separated_by_its_bisector_not_remembered_as_a_wall():
    domain = _open_domain()
    robot = make_strategy("bvc", StrategyContext(domain=domain,
                                                 robot=RobotSpec(sensor_radius=3.5)))
    pose, other = np.array([2.0, 3.0, 0.0]), np.array([3.0, 3.0])
    from coverage_ros.core.offline.rangesim import simulate_scan

    scan = simulate_scan(domain.geometry, pose, LidarSpec(), other[None], np.array([0.105]))
    d = robot.update(Observation(0, pose, 0.0, scan),
                     [Neighbour(1, SharedState(position=other))])
    assert d.cell_polygon[:, 0].max() <= 2.5 - robot.radius + TOL  # bisector x = 2.5, buffered
    rows, cols = np.nonzero(robot.memory.hits)
    assert len(rows) > 0  # the arena walls are remembered ...
    remembered = robot.memory.centers(rows, cols)
    assert np.hypot(*(remembered - other).T).min() > 0.5  # ... the neighbour is not
    assert d.goal[0] < 2.5  # the peak lies beyond the neighbour: wait at the bisector


# ---------------------------------------------------------------------------- U-shaped trap
U_TRAP = {"name": "u_trap", "resolution": 0.05, "bounds": [0.0, 0.0, 10.0, 8.0],
          "obstacles": [  # a cup open towards the robot, the peak behind its bottom
              {"type": "wall", "from": [5.0, 2.5], "to": [5.0, 5.5], "thickness": 0.1},
              {"type": "wall", "from": [3.3, 2.5], "to": [5.0, 2.5], "thickness": 0.1},
              {"type": "wall", "from": [3.3, 5.5], "to": [5.0, 5.5], "thickness": 0.1}],
          "density": {"type": "gaussian_mixture",
                      "components": [{"mean": [7.5, 4.0], "sigma": 0.8}]}}
U_PEAK = np.array([[7.5, 4.0]])


def _u_trial(**params: object) -> TrialOutcome:
    spec = parse_world(U_TRAP)
    robot = RobotSpec(v_max=0.5)
    domain = CoverageDomain.from_grid(spec.grid, robot.radius, spec.density)
    ctx = [StrategyContext(domain=domain, robot=replace(robot, sensor_radius=3.5))]
    return run_trial(domain, world_clearance(spec), np.array([[2.0, 4.0, 0.0]]), U_PEAK, ctx,
                     strategy=strategy_choice("bvc", params), dt=0.5, time_limit=60.0,
                     detect_radius=0.5, arrive_radius=0.5)


def test_u_trap_plain_move_to_centroid_deadlocks_and_the_guided_map_escapes():
    plain = _u_trial(guided=False)
    assert plain.converged and not plain.success and plain.deadlocked
    assert 3.3 < plain.positions[-1, 0, 0] < 5.0  # stuck at the bottom of the cup
    guided = _u_trial()
    assert guided.success and not guided.collided
    assert np.hypot(*(guided.positions[-1, 0] - U_PEAK[0])) < 0.5
    assert guided.min_clearance >= 0.0


def test_u_trap_stalled_centroid_escapes_with_a_weak_gain(monkeypatch):
    # gamma = 2/m: the cell's shape balances the pull of the two ways around the cup and the
    # centroid stalls at the mouth; the escape to the cell's lowest cost-to-go breaks the tie.
    assert _u_trial(gamma=2.0).success
    monkeypatch.setattr(bvc_strategy, "ESCAPE_DESCENT_CELLS", math.inf)
    stalled = _u_trial(gamma=2.0)
    assert stalled.deadlocked and stalled.positions[-1, 0, 0] < 3.3


# ---------------------------------------------------------------------------- Table I trials
TRIAL_SEED = 2000  # first scenario seed; trial k uses TRIAL_SEED + k
TRIALS = 30
TRIAL_ROBOT = RobotSpec(v_max=0.5, lidar=LidarSpec(beams=120, range_max=2.5))


def _trial(k: int, **params: object) -> TrialOutcome:
    setup = cluttered_trial(np.random.default_rng(TRIAL_SEED + k), size=12.0, obstacles=18,
                            robots=3, peaks=3, sigma=1.0, peak_spacing=4.0)
    ctx = [StrategyContext(domain=setup.domain, robot=replace(TRIAL_ROBOT, sensor_radius=2.5),
                           robot_id=i) for i in range(3)]
    return run_trial(setup.domain, world_clearance(setup.world), setup.starts, setup.peaks,
                     ctx, strategy=strategy_choice("bvc", params), dt=0.5, time_limit=30.0,
                     detect_radius=2.5, arrive_radius=1.0)


@pytest.mark.slow
def test_thirty_random_three_peak_trials_succeed_without_collisions():
    outcomes = [_trial(k) for k in range(TRIALS)]
    row = table_row(outcomes)
    print(f"bvc guided: {row}")
    assert row.collisions == 0
    assert min(o.min_clearance for o in outcomes) >= 0.0
    assert min(o.min_separation for o in outcomes) >= 0.0
    assert row.success_rate >= 0.9  # paper: 96.67 %
    # A robot left beside its neighbour at a shared peak heads for the one nobody attends: all
    # three peaks found in at least the paper's 27 of 30 trials (without it: 3 of 30).
    assert row.all_peaks >= 27
    alone = [_trial(k, seek_peaks=False) for k in range(10)]
    assert sum(o.detected.all() for o in alone) <= 5
    # The scenarios do trap the plain move-to-centroid policy.
    plain = [_trial(k, guided=False) for k in range(10)]
    print(f"bvc plain (first 10): {table_row(plain)}")
    assert success_rate(plain) <= 0.6
    assert all(not o.collided for o in plain)


# ---------------------------------------------------------------------------- metrics
def _outcome(detected_at, converged=True, at_targets=True, collided=False, duration=5.0):
    return TrialOutcome(np.array(detected_at, dtype=float), collided, converged, at_targets,
                        duration, 0.1, 0.1, np.zeros((1, 1, 2)))


def test_table_one_metrics():
    outs = [_outcome([1.0, 2.0, 3.0], duration=3.0),  # every peak found
            _outcome([1.0, np.inf, 2.0], duration=7.0),  # converged at targets, one peak missed
            _outcome([1.0, np.inf, np.inf], at_targets=False),  # deadlocked
            _outcome([1.0, 2.0, 3.0], collided=True)]  # collision
    assert coverage_ratio(outs) == pytest.approx(9 / 12)
    assert [o.success for o in outs] == [True, True, False, False]
    assert success_rate(outs) == 0.5
    assert average_time(outs) == pytest.approx(5.0)
    row = table_row(outs)
    assert (row.all_peaks, row.trials, row.collisions) == (2, 4, 1)
    assert math.isnan(average_time([outs[2]]))


def test_peak_detection_needs_range_and_line_of_sight():
    spec = parse_world({"name": "w", "resolution": 0.05, "bounds": [0, 0, 6, 4], "obstacles": [
        {"type": "wall", "from": [3.0, 0.0], "to": [3.0, 3.0], "thickness": 0.1}]})
    peaks = np.array([[4.0, 1.0], [4.0, 3.5]])
    seen = peaks_detected(spec.grid, peaks, np.array([[2.0, 1.0], [2.0, 3.5]]), 2.5)
    assert seen.tolist() == [False, True]  # the first behind the wall
    assert not peaks_detected(spec.grid, peaks, np.array([[0.5, 3.5]]), 2.5).any()  # too far


def test_world_clearance_is_exact():
    setup = cluttered_trial(np.random.default_rng(3), size=8.0, obstacles=10)
    clear = world_clearance(setup.world)
    pts = np.random.default_rng(4).uniform(0.0, 8.0, (300, 2))
    want = [clearance(setup.world, *p) for p in pts]
    assert np.allclose(clear(pts), want)


# ---------------------------------------------------------------------------- offline runner
def test_runs_through_run_offline_on_the_field_world():
    spec = load_world(WORLDS / "field.yaml")
    domain = CoverageDomain.from_grid(spec.grid, spec.robot.radius, spec.density)
    starts = cluster_starts(spec.grid, 3, spec.robot.radius, np.random.default_rng(3))
    result = run_offline(domain, "bvc", starts, config=OfflineConfig(max_iterations=60))
    assert result.converged
    clear = world_clearance(spec)
    t = np.linspace(0.0, 1.0, 11)[:, None, None]
    for a, b in zip(result.positions[:-1], result.positions[1:], strict=True):
        path = (a[None] + t * (b - a)[None]).reshape(-1, 2)  # straight moves to the goals
        assert clear(path).min() >= spec.robot.radius
        gap = np.hypot(*(b[:, None] - b[None]).transpose(2, 0, 1))[np.triu_indices(3, 1)]
        assert gap.min() >= 2 * spec.robot.radius
    # Two robots own a peak (guided to it); the third, beside an owner with no peak left to
    # seek, covers round it under the importance density.
    assert sorted(d.mode for d in result.decisions) == ["guided", "guided", "plain"]
    for i, d in enumerate(result.decisions):
        assert _point_polygon_distance(result.positions[-2, i][None], d.cell_polygon)[0] == 0
    # Everyone ended where the density is high, and both areas of interest have a robot (the
    # cluster starts by the second; one robot went on to the first, which nobody attended).
    final = domain.density.max() * 0.5
    w = [domain.density[tuple(domain.geometry.world_to_cell(p[None])[0])]
         for p in result.positions[-1]]
    assert min(w) > final
    areas = np.array([[4.0, 9.5], [13.0, 6.0]])
    gap = np.hypot(*(result.positions[-1][:, None] - areas[None]).transpose(2, 0, 1))
    assert np.all(gap.min(axis=0) < 1.0)



@pytest.mark.slow
@pytest.mark.parametrize("world", ["l_shape", "tb3_sandbox"])
def test_a_cluster_spreads_under_a_uniform_density(world):
    """With no density peak to be guided to, each robot is guided to the middle of the
    reachable part of its own Voronoi region: the team spreads about as well as geodesic
    Lloyd (before, the guide was the robot's own spot and the cluster barely moved). Maps a
    sensing radius (3.5 m) spans; in the office's rooms a local method is slower (README)."""
    from conftest import shared_map

    from coverage_ros.core.geodesic.tessellation import Generator, tessellate
    from coverage_ros.core.offline.lloyd_team import GeodesicTeam, solve_lloyd
    from coverage_ros.core.world import load_world
    from coverage_ros.core.world.placement import cluster_starts

    path = WORLDS / f"{world}.yaml" if world == "l_shape" else shared_map(world)
    spec = load_world(path)
    domain = CoverageDomain.from_grid(spec.grid, 0.105)
    starts = cluster_starts(spec.grid, 4, 0.105, np.random.default_rng(3))

    def cost(points):
        return tessellate(domain, [Generator(p, 0.0) for p in points]).cost

    bvc = run_offline(domain, "bvc", starts, config=OfflineConfig(max_iterations=150))
    # Geodesic Lloyd from the same start, as coverage-plan steps the whole team (the geodesic
    # robots' closet escape finds no lower configuration on these maps, at 20-50 times the time)
    lloyd = solve_lloyd(GeodesicTeam(domain), starts[:, :2], tolerance=0.005, max_steps=500)
    start, H, best = cost(starts[:, :2]), cost(bvc.positions[-1]), cost(lloyd.positions[-1])
    assert {d.mode for d in bvc.decisions} <= {"guided", "escape"}
    assert H <= 0.6 * start and H <= 1.3 * best, (start, H, best)


def test_what_a_scan_sees_free():
    from coverage_ros.core.strategies import Scan

    ranges = np.full(360, np.inf)
    ranges[0] = 1.0  # a wall 1 m ahead (beam 0 at angle_min = -pi: behind the robot)
    ranges[180] = 2.0  # straight ahead: a return at 2 m
    ranges[90] = np.nan  # an invalid return shows nothing
    scan = Scan(ranges, -math.pi, 2 * math.pi / 360, 0.1, 3.5)
    pose = np.array([5.0, 5.0, 0.0])
    pts = np.array([[6.9, 5.0], [7.1, 5.0], [4.5, 5.0], [3.9, 5.0], [5.0, 8.4], [5.0, 8.6],
                    [5.0, 4.0]])
    assert scan.sees(pts, pose).tolist() == [True, False, True, False, True, False, False]
    # The robot turned by 90 degrees: 'ahead' now points along +y.
    assert scan.sees(np.array([[5.0, 6.9], [5.0, 7.1]]), np.array([5.0, 5.0, math.pi / 2])
                     ).tolist() == [True, False]


def test_a_receding_centroid_is_followed_past_the_arrival_tolerance():
    """A centroid a few cm ahead that keeps moving ahead (a cell face receding as the robot
    follows it) is sent to the navigation one and a half tolerances along, inside the cell; a
    centroid that turned back is sent as it is (no oscillation)."""
    from coverage_ros.core.world.grid import GridMap

    domain = CoverageDomain.from_grid(GridMap(np.zeros((60, 60), np.int8), 0.05), 0.105)
    robot = bvc_strategy.BvcStrategy(StrategyContext(domain=domain, robot_id=0))
    cell = bvc_strategy.buffered_cell(np.array([1.5, 1.5]), np.zeros((0, 2)), np.zeros((0, 2)),
                                      0.105, 1.0)
    p = np.array([1.5, 1.5])
    first = robot._navigation_goal(p, p + [0.03, 0.0], np.array([0.03, 0.0]), 0.03, cell)
    assert np.allclose(first, p + [0.03, 0.0])  # no history yet: the centroid itself
    ahead = robot._navigation_goal(p, p + [0.03, 0.0], np.array([0.03, 0.0]), 0.03, cell)
    assert np.allclose(ahead, p + [0.075, 0.0])  # 1.5 x the 0.05 m tolerance along
    back = robot._navigation_goal(p, p - [0.02, 0.0], np.array([-0.02, 0.0]), 0.02, cell)
    assert np.allclose(back, p - [0.02, 0.0])
    far = robot._navigation_goal(p, p - [0.3, 0.0], np.array([-0.3, 0.0]), 0.3, cell)
    assert np.allclose(far, p - [0.3, 0.0])

