"""Strategy ``tangentbug``: TangentBug on range scans, virtual generators, projection of
unreachable targets (Breitenmoser et al. 2010, Alg. 1-2, section III-A, Figs. 3-4).

Scans are simulated on the occupancy grid (:mod:`coverage_ros.core.offline.rangesim`), robots are
integrated as unicycles and never enter a cell outside the configuration space. Expected
positions are computed from the rasterized obstacles (what the lidar actually sees), with
tolerances budgeted from the scan's range quantisation, the reference's own resolution and the
sampling of the followed contour.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import WORLDS
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy import ndimage
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.euclidean import euclidean_cell, euclidean_labels
from coverage_ros.core.geodesic.tessellation import Generator
from coverage_ros.core.metrics import euclidean_cost
from coverage_ros.core.offline.rangesim import STEP_CELLS, simulate_scan
from coverage_ros.core.offline.runner import OfflineConfig, run_offline
from coverage_ros.core.strategies import (
    Neighbour,
    Observation,
    SharedState,
    StrategyContext,
    make_strategy,
    strategy_choice,
)
from coverage_ros.core.strategies.tangentbug.bug import BugConfig, BugMode, TangentBug
from coverage_ros.core.strategies.tangentbug.scan_geometry import (
    closest_on_polyline,
    free_lengths,
    on_obstacle_side,
    scan_nodes,
)
from coverage_ros.core.strategies.tangentbug.strategy import (
    NEIGHBOUR_MASK_MARGIN,
    STUCK_DISTANCE,
    STUCK_TIME,
    decision_costs,
    team_costs,
)
from coverage_ros.core.world import LidarSpec, RobotSpec, load_world, parse_world
from coverage_ros.errors import ConfigError

RES = 0.05  # [m] grid resolution of every world here
#: 120 beams (3 degrees): the returns of a wall 3.5 m away are 18 cm apart, closer than the
#: 2 x 0.205 m clearance disc, so nothing the robot could pass through falls between beams;
#: a third of the default LDS-01 beams keeps the team runs fast.
ROBOT = RobotSpec(lidar=LidarSpec(beams=120))
MARGIN = 0.10  # [m] default follow_margin
CLEARANCE = ROBOT.radius + MARGIN  # [m] distance TangentBug keeps from obstacle surfaces
TOL = 0.05  # [m] StrategyContext default convergence tolerance = arrival radius
DT = 0.5  # [s] the robot node's default control period (control_rate 2 Hz)
#: [m] a return lies up to one ray-march step behind the true surface (rangesim).
SCAN_BIAS = STEP_CELLS * RES
#: [m] resolution of the reference contour (grid upsampled 5x for the distance transform).
REF_RES = RES / 5
#: [m] radial tracking error of boundary following (sweep over 1-degree directions).
TRACKING = 0.01


# ---------------------------------------------------------------------------- helpers
def _world(bounds, obstacles):
    spec = parse_world({"name": "t", "resolution": RES, "bounds": bounds,
                        "obstacles": obstacles})
    return spec, CoverageDomain.from_grid(spec.grid, ROBOT.radius, spec.density)


def _bug() -> TangentBug:
    return TangentBug(BugConfig(clearance=CLEARANCE, robot_radius=ROBOT.radius,
                                v_max=ROBOT.v_max, w_max=ROBOT.w_max, goal_tolerance=TOL))


def _drive(spec, domain, bug, start, goal, steps=600, dt=DT, neighbour=None):
    """Run ``bug`` from ``start (x, y, yaw)``; returns (path (T, 2), modes, rejected moves).
    A ``neighbour (2,)`` [m] robot stands still there: its scan returns are masked as the
    strategy masks them (given to the bug as ``hidden``)."""
    bug.reset(np.asarray(goal, dtype=np.float64))
    pose = np.asarray(start, dtype=np.float64).copy()
    path, modes, rejected = [pose[:2].copy()], [], 0
    others = None if neighbour is None else np.asarray(neighbour, dtype=np.float64)[None]
    for _ in range(steps):
        scan = simulate_scan(spec.grid, pose, ROBOT.lidar, others, np.array([ROBOT.radius]))
        pts, hidden = scan.points(pose), None
        if others is not None:
            off = np.hypot(*(pts - others[0]).T) > ROBOT.radius + NEIGHBOUR_MASK_MARGIN
            pts, hidden = pts[off], pts[~off]
        cmd = bug.step(pose, pts, scan.range_max, hidden)
        modes.append(cmd.mode)
        if bug.done:
            break
        heading = pose[2] + 0.5 * cmd.w * dt
        q = pose[:2] + cmd.v * dt * np.array([math.cos(heading), math.sin(heading)])
        if domain.is_free_point(q):
            pose[:2] = q
        else:
            rejected += 1
        pose[2] += cmd.w * dt
        path.append(pose[:2].copy())
    return np.array(path), modes, rejected


def _projection_reference(grid, target: np.ndarray, clearance: float) -> np.ndarray:
    """The point at least ``clearance`` from every occupied cell that is closest to
    ``target`` (distance transform on the grid upsampled to REF_RES)."""
    k = int(round(RES / REF_RES))
    occ = np.kron(grid.occupied_mask(), np.ones((k, k), dtype=bool))
    dist = ndimage.distance_transform_edt(~occ) * REF_RES
    rows, cols = np.nonzero(dist >= clearance)
    xy = grid.grid_to_world(np.stack([(cols + 0.5) / k, (rows + 0.5) / k], axis=-1))
    return xy[int(np.argmin(np.hypot(*(xy - target).T)))]


def _geodesic_length(domain, a, b) -> float:
    na = int(domain.graph.node_of_cell(domain.geometry.world_to_cell(np.asarray(a))[None])[0])
    nb = int(domain.graph.node_of_cell(domain.geometry.world_to_cell(np.asarray(b))[None])[0])
    return float(dijkstra(domain.graph.csr, indices=na)[nb])


def _labels_cost(domain, labels_of, positions) -> float:
    """Cost of ``positions (n, 2)`` with the partition of generators ``labels_of``."""
    lab = euclidean_labels(domain, [Generator(p) for p in labels_of]).ravel()
    ok = lab >= 0
    X, Y = domain.geometry.all_cell_centers()
    q = np.stack([X.ravel(), Y.ravel()], axis=-1)[ok]
    d2 = ((q - positions[lab[ok]]) ** 2).sum(axis=1)
    return float((d2 * domain.mass_element.ravel()[ok]).sum())


def _team(domain, starts, max_iterations):
    contexts = [StrategyContext(domain=domain, robot=ROBOT, robot_id=i)
                for i in range(len(starts))]
    return run_offline(domain, "tangentbug", np.asarray(starts, dtype=np.float64), contexts,
                       OfflineConfig(max_iterations=max_iterations, dt=DT))


# ---------------------------------------------------------------------------- kernels
@settings(max_examples=40, deadline=None)
@given(pts=st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3)), min_size=1, max_size=8),
       angle=st.floats(-math.pi, math.pi), radius=st.floats(0.05, 0.5))
def test_free_lengths_match_ray_sampling(pts, angle, radius):
    """Parity with the obvious method: march along the ray until it enters a disc."""
    P = np.array(pts)
    P = P[np.hypot(*P.T) > radius + 1e-3]  # start outside every disc
    u = np.array([math.cos(angle), math.sin(angle)])
    # A ray that grazes a disc (within 1e-6 m) is ambiguous for the 1 mm march; the exact
    # tangent is checked on its own below.
    ahead = P[P @ u > 0]
    assume(np.all(np.abs(np.abs(ahead @ np.array([-u[1], u[0]])) - radius) > 1e-6))
    horizon = 4.0
    got = free_lengths(P, u[None], radius, horizon)[0]
    t = np.arange(0.0, horizon, 1e-3)
    ray = t[:, None] * u
    inside = np.zeros(len(t), dtype=bool)
    for q in P:
        inside |= np.hypot(*(ray - q).T) < radius
    want = t[np.argmax(inside)] if inside.any() else horizon
    assert got == pytest.approx(want, abs=2e-3)


def test_a_ray_that_touches_a_disc_is_blocked_where_it_touches():
    # Found by hypothesis: a ray exactly tangent to a disc. Touching counts as contact (the
    # safe answer for a robot's clearance).
    got = free_lengths(np.array([[1.0, 0.05]]), np.array([[1.0, 0.0]]), 0.05, 4.0)[0]
    assert got == pytest.approx(1.0, abs=1e-6)


def test_free_lengths_never_block_backing_off():
    wall = np.array([[0.1, y] for y in np.linspace(-1, 1, 41)])  # 0.1 m ahead, radius 0.2
    L = free_lengths(wall, np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]]), 0.2, 3.0)
    assert L[0] == 0.0 and L[1] == 3.0
    assert L[2] == 0.0  # sliding along it would keep it too close (points ahead block)


def test_scan_nodes_are_segment_ends_moved_by_the_clearance():
    seg = np.array([[2.0, y] for y in np.linspace(-1.0, 1.0, 41)])
    nodes, opens = scan_nodes(seg, 0.2, 0.4)
    order = np.argsort(nodes[:, 1])
    for end, node, side in zip(([2.0, -1.0], [2.0, 1.0]), nodes[order], opens[order],
                               strict=True):
        end = np.array(end)
        assert np.hypot(*(node - end)) == pytest.approx(0.2)
        assert abs(np.dot(node - end, end)) < 1e-9  # sideways, perpendicular to the bearing
        assert side == np.sign(end[1])  # the upper end opens counter-clockwise


def test_loop_memory_geometry():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)  # counter-clockwise
    pts = np.array([[0.5, 0.5], [3.0, 0.5]])
    # Obstacle on the left of a counter-clockwise loop: the loop went round the obstacle.
    assert on_obstacle_side(square, 1, pts).tolist() == [True, False]
    # Obstacle on the left of a clockwise loop: it went round the free space (an outer wall).
    assert on_obstacle_side(square[::-1], 1, pts).tolist() == [False, True]
    np.testing.assert_allclose(closest_on_polyline(square, np.array([0.3, -2.0])), [0.3, 0.0])
    np.testing.assert_allclose(closest_on_polyline(square, np.array([0.4, 0.45])), [0.0, 0.45])


# ---------------------------------------------------------------------------- configuration
def test_parameters_are_validated():
    _, domain = _world([0, 0, 2, 2], [])
    ctx = StrategyContext(domain=domain, robot=ROBOT)
    with pytest.raises(ConfigError, match=r"unknown parameters.*speed"):
        make_strategy(strategy_choice("tangentbug", {"speed": 1.0}), ctx)
    with pytest.raises(ConfigError, match=r"lookahead.*> 0"):
        make_strategy(strategy_choice("tangentbug", {"lookahead": -0.2}), ctx)
    with pytest.raises(ConfigError, match="clearance"):
        BugConfig(clearance=0.1, robot_radius=0.105, v_max=0.22, w_max=2.84)
    # Following a wall at the brake's own radius (robot radius + SAFETY_MARGIN), the robot
    # has no room ahead and stalls for ever (an e-puck with follow_margin 0.02 m did).
    with pytest.raises(ConfigError, match="clearance"):
        BugConfig(clearance=0.055, robot_radius=0.035, v_max=0.13, w_max=4.8)
    with pytest.raises(ConfigError, match="clearance"):
        make_strategy(strategy_choice("tangentbug", {"follow_margin": 0.02}), ctx)
    with pytest.raises(ConfigError, match="loop_tolerance"):
        BugConfig(clearance=0.2, robot_radius=0.1, v_max=0.2, w_max=2.0, goal_tolerance=0.2,
                  loop_tolerance=0.1)
    s = make_strategy(strategy_choice("tangentbug", {"follow_margin": 0.2, "loop_tolerance": 0.3}),
                      ctx)
    assert s.bug.config.clearance == pytest.approx(ROBOT.radius + 0.2)



# ---------------------------------------------------------------------------- TangentBug
def test_tangentbug_reaches_a_goal_behind_a_concave_obstacle():
    """The robot starts inside a cup whose bottom hides the goal: motion-to-goal meets a local
    minimum, boundary following leads out of the cup, and the robot leaves the boundary for
    the goal."""
    cup = [{"type": "box", "center": [4.0, 5.1], "size": [3.2, 0.2]},
           {"type": "box", "center": [2.5, 4.0], "size": [0.2, 2.4]},
           {"type": "box", "center": [5.5, 4.0], "size": [0.2, 2.4]}]
    spec, domain = _world([0, 0, 8, 8], cup)
    start, goal = np.array([4.0, 4.0, 0.0]), np.array([4.0, 6.5])
    path, modes, rejected = _drive(spec, domain, _bug(), start, goal)
    assert modes[-1] is BugMode.REACHED
    assert np.hypot(*(path[-1] - goal)) <= TOL
    assert BugMode.BOUNDARY_FOLLOWING in modes and rejected == 0
    # Never closer to a wall than the robot radius (it keeps CLEARANCE, the brake the rest).
    cells = spec.grid.world_to_cell(path)
    assert spec.grid.clearance()[cells[:, 0], cells[:, 1]].min() > ROBOT.radius
    # No shorter than the shortest path of the configuration space, no longer than Bug
    # algorithms' bound: straight distance plus the perimeter of the obstacle's contour.
    length = float(np.hypot(*np.diff(path, axis=0).T).sum())
    contour = 2 * (3.2 + 2.4) + 2 * 2.2 + 2.8 - 0.2 + 2 * math.pi * CLEARANCE
    assert _geodesic_length(domain, start[:2], goal) - RES <= length
    assert length <= np.hypot(*(goal - start[:2])) + contour


def test_tangentbug_projects_an_unreachable_goal_after_one_loop():
    """Goal inside a C-shaped obstacle, 0.5 m behind the face the robot meets first and 0.3 m
    behind the bottom of the notch on the far side. One loop round it (no leave point), then
    the robot stops at the boundary position closest to the goal it recorded on the way
    (Breitenmoser et al. 2010, section III-A) - in the notch, not where the loop began. A leave
    margin larger than that 0.2 m gain keeps TangentBug from leaving the boundary for the notch
    when it sees it, so that the loop starts on the near face."""
    arms = [{"type": "box", "center": [4.0, 4.5], "size": [2.0, 1.0]},
            {"type": "box", "center": [4.0, 2.5], "size": [2.0, 1.0]},
            {"type": "box", "center": [4.6, 3.5], "size": [0.8, 1.0]}]  # notch x < 4.2
    spec, domain = _world([0, 0, 8, 7], arms)
    goal = np.array([4.5, 3.5])
    bug = TangentBug(BugConfig(clearance=CLEARANCE, robot_radius=ROBOT.radius,
                               v_max=ROBOT.v_max, w_max=ROBOT.w_max, goal_tolerance=TOL,
                               leave_margin=1.0))
    path, modes, rejected = _drive(spec, domain, bug, [7.0, 3.5, math.pi], goal, steps=500)
    assert modes[-1] is BugMode.PROJECTED and bug.unreachable and rejected == 0
    assert BugMode.PROJECTING in modes
    # One loop: the length of the clearance contour of the C (12.4 m of sides; its 6 convex
    # corners add quarter circles, its 2 concave ones cut 2 * CLEARANCE each), up to the
    # rasterization (+ one cell per side), the rounded concave corners and the closure gap.
    perimeter = 12.4 + 6 * 0.5 * math.pi * CLEARANCE - 2 * 2 * CLEARANCE
    loop = float(np.hypot(*np.diff(bug.loop, axis=0).T).sum())
    assert 0.95 * perimeter <= loop <= 1.05 * perimeter
    # The projection: as close to the goal as the rasterized obstacle's clearance contour
    # allows, and much closer than where the loop began.
    ref = _projection_reference(spec.grid, goal, CLEARANCE)
    d_ref = float(np.hypot(*(ref - goal)))
    d_best = float(np.hypot(*(bug.best - goal)))
    assert d_best == pytest.approx(d_ref, abs=SCAN_BIAS + REF_RES + TRACKING)
    assert np.hypot(*(bug.loop[0] - goal)) >= d_best + 0.1
    # Across the notch bottom the distance is flat near its minimum: a radial wobble e moves
    # the minimum by up to sqrt(2 d e), plus half a control step of travel.
    along = abs(bug.best[1] - ref[1])
    assert along <= math.sqrt(2 * d_ref * TRACKING) + 0.5 * ROBOT.v_max * DT
    assert np.hypot(*(path[-1] - bug.best)) <= TOL


def test_a_goal_ray_free_only_up_to_the_horizon_does_not_end_boundary_following():
    """Found by the Breitenmoser benchmark (U world, five robots): a goal inside the block of
    the U world, which stands in from the top wall. Following the block's face up leads along
    the top wall into the far corner, from where the goal ray is free up to the lidar's horizon
    (3.5 m) but meets the block beyond it. Leaving the boundary there (the goal looked
    "visible") brought the robot back to the same face, where following started afresh - for
    ever. TangentBug leaves only for a point closer than any it followed (d_reach <
    d_followed) or a goal really in sight; then the loop round the whole boundary completes
    and the goal is projected onto the block's nearest face."""
    spec = load_world(WORLDS / "u_shape.yaml")
    domain = CoverageDomain.from_grid(spec.grid, ROBOT.radius, spec.density)
    goal = np.array([5.2, 3.95])  # block: x 3.5-6.5, y 2.5-8; nearest face x = 6.5
    path, modes, rejected = _drive(spec, domain, _bug(), [3.0, 3.1, 0.0], goal, steps=900)
    assert modes[-1] is BugMode.PROJECTED and rejected == 0
    # Each boundary-following episode begins closer to the goal than the one before.
    starts = [k for k in range(1, len(modes)) if modes[k] is BugMode.BOUNDARY_FOLLOWING
              and modes[k - 1] is not BugMode.BOUNDARY_FOLLOWING]
    d = np.hypot(*(path[starts] - goal).T)
    assert len(starts) >= 2 and np.all(np.diff(d) < 0)
    ref = _projection_reference(spec.grid, goal, CLEARANCE)
    np.testing.assert_allclose(ref, [6.5 + CLEARANCE, goal[1]], atol=REF_RES)
    assert np.hypot(*(path[-1] - ref)) <= SCAN_BIAS + REF_RES + TRACKING + TOL


def test_space_a_neighbour_shadows_does_not_count_for_leaving_a_boundary():
    """Found by the Breitenmoser benchmark (U world, seed 1): a goal 0.21 m inside the face of
    the U world's block; a converged neighbour stands still in the left arm. Its returns are
    masked (the robot may drive through it), which left no returns in its shadow: from the
    left wall the shadowed strip along the face looked free, closer to the goal than the
    followed face, so the robot left the wall for it, found the face again and started
    following afresh - for ever. The masked returns still bound what the robot sees: it
    follows the whole boundary once and projects the goal onto the face."""
    spec = load_world(WORLDS / "u_shape.yaml")
    domain = CoverageDomain.from_grid(spec.grid, ROBOT.radius, spec.density)
    goal = np.array([3.709, 5.295])  # block: x 3.5-6.5, y 2.5-8
    path, modes, rejected = _drive(spec, domain, _bug(), [2.16, 3.21, 1.3], goal, steps=600,
                                   neighbour=[1.36, 5.98])
    assert modes[-1] is BugMode.PROJECTED and rejected == 0
    starts = [k for k in range(1, len(modes)) if modes[k] is BugMode.BOUNDARY_FOLLOWING
              and modes[k - 1] is not BugMode.BOUNDARY_FOLLOWING]
    assert len(starts) == 1  # one boundary-following episode: the loop
    ref = _projection_reference(spec.grid, goal, CLEARANCE)
    # (the face at x = 3.5 lies on a cell border: the grid rasterizes it one cell out)
    np.testing.assert_allclose(ref, [3.5 - CLEARANCE, goal[1]], atol=RES + REF_RES)
    assert np.hypot(*(path[-1] - ref)) <= SCAN_BIAS + REF_RES + TRACKING + TOL


def test_a_goal_seen_only_through_a_neighbours_shadow_is_not_in_sight():
    """Found by the Breitenmoser benchmark (Fig. 5, e-puck scale): the robot follows the
    boundary round a goal 0.1 m inside a block; from the wall opposite the block the goal ray
    runs through a neighbour, whose masked returns left the block's face behind it unseen, so
    the goal looked in sight and the robot left the wall for it, met the face and followed it
    afresh, for ever. Seen past the neighbour's returns, the goal is not in sight: one loop,
    then the projection onto the face."""
    spec, domain = _world([0, 0, 3, 3], [{"type": "box", "center": [1.5, 1.95],
                                           "size": [1.0, 2.1]}])  # x 1-2, from the top wall
    goal = np.array([1.1, 1.8])
    path, modes, rejected = _drive(spec, domain, _bug(), [0.4, 1.0, 1.5], goal, steps=300,
                                   neighbour=[0.5, 1.8])
    assert modes[-1] is BugMode.PROJECTED and rejected == 0
    starts = [k for k in range(1, len(modes)) if modes[k] is BugMode.BOUNDARY_FOLLOWING
              and modes[k - 1] is not BugMode.BOUNDARY_FOLLOWING]
    assert len(starts) == 1
    ref = _projection_reference(spec.grid, goal, CLEARANCE)
    assert np.hypot(*(path[-1] - ref)) <= SCAN_BIAS + REF_RES + TRACKING + TOL


# ---------------------------------------------------------------------------- strategy
def test_targets_are_taken_again_for_a_new_neighbour_and_coincident_generators_part():
    """A robot whose first update came before its neighbours' states has the whole map as
    its cell and the map's centroid as its target: hearing a neighbour makes it take its
    targets again. A virtual generator found on a neighbour's (they would share one cell and
    one centroid for ever) starts again from the robot's own position."""
    spec, domain = _world([0, 0, 6, 4], [])
    s = make_strategy("tangentbug", StrategyContext(domain=domain, robot=ROBOT))
    pose = np.array([1.0, 2.0, 0.0])
    scan = simulate_scan(spec.grid, pose, ROBOT.lidar)
    alone = s.update(Observation(0, pose, 10.0, scan), [])
    np.testing.assert_allclose(alone.details.virtual_target, [3.0, 2.0], atol=0.05)
    other = Neighbour(1, SharedState(position=np.array([5.0, 2.0]),
                                     virtual=np.array([5.0, 2.0])))
    heard = s.update(Observation(0, pose, 10.5, scan), [other])
    half = euclidean_cell(domain, Generator(heard.shared.virtual), [Generator(other.position)])
    np.testing.assert_allclose(heard.details.virtual_target, half.centroid)
    assert heard.details.virtual_target[0] < 2.0  # the left half's centroid, not the map's
    # The neighbour's virtual generator on this one's: this one starts again from the robot.
    on_top = Neighbour(1, SharedState(position=np.array([5.0, 2.0]),
                                      virtual=heard.shared.virtual.copy()))
    parted = s.update(Observation(0, pose, 10.5, scan), [on_top])  # (no time to move)
    np.testing.assert_allclose(parted.shared.virtual, pose[:2])


def test_a_robot_stuck_behind_a_neighbour_lets_tangentbug_see_it():
    """A neighbour stands in the way to the target: its scan returns are masked, so TangentBug
    drives straight at it (the node's safety filter would stop the robot). After 5 s without
    getting 0.1 m further the robot's bug sees the neighbour as an obstacle and turns off the
    straight line; once it moves on, the neighbour is masked again."""
    spec, domain = _world([0, 0, 6, 4], [])
    s = make_strategy("tangentbug", StrategyContext(domain=domain, robot=ROBOT))
    pose = np.array([1.0, 2.0, 0.0])
    other = Neighbour(1, SharedState(position=np.array([1.45, 2.0]),
                                     virtual=np.array([0.2, 2.0]), extra={"radius": 0.105}))
    scan = simulate_scan(spec.grid, pose, ROBOT.lidar, others=np.array([[1.45, 2.0]]),
                         other_radii=np.array([0.105]))
    s.update(Observation(0, pose, 10.0, scan), [other])  # targets: the cell right of x = 0.6
    s.real_target = s.virtual_target = np.array([4.0, 2.0])
    s.bug.reset(s.real_target)
    first = s.update(Observation(0, pose, 10.5, scan), [other])
    assert first.velocity[0] > 0 and abs(first.heading) < 1e-6  # straight at the neighbour
    for t in (12.0, 14.0, 16.0):
        later = s.update(Observation(0, pose, t, scan), [other])
    assert s._unmasked and abs(later.heading) > 0.1  # round it, not through it
    moved = pose + np.array([0.0, 0.3, 0.0])
    s.update(Observation(0, moved, 16.5, scan), [other])
    assert not s._unmasked


def test_a_robot_arriving_at_creeping_targets_is_not_stuck():
    """Found by the Breitenmoser benchmark (Fig. 5, e-puck scale): early on, Lloyd steps are
    small while the neighbours spread, and a robot that arrived at each of its targets had
    moved less than STUCK_DISTANCE in STUCK_TIME - it counted as stuck, its bug saw the
    neighbours, and a target near one was "projected" on the spot and kept for good.
    Arriving is progress: taking new targets starts the stuck clock again."""
    spec = parse_world({"name": "t", "resolution": 0.01, "bounds": [0, 0, 3, 2],
                        "obstacles": []})  # fine cells: the centroid creeps, not jumps
    domain = CoverageDomain.from_grid(spec.grid, ROBOT.radius, spec.density)
    tol = 0.005  # [m] below the centroid's creep per Lloyd update
    s = make_strategy("tangentbug", StrategyContext(domain=domain, robot=ROBOT,
                                                    convergence_tolerance=tol))
    pose, path, steps = np.array([0.75, 1.0, 0.0]), [], []
    for k in range(30):  # 15 s; the neighbour's virtual generator creeps toward the robot
        v = np.array([2.5 - 0.02 * k, 1.0])
        d = s.update(Observation(0, pose, 10.0 + 0.5 * k, simulate_scan(spec.grid, pose,
                                                                         ROBOT.lidar)),
                     [Neighbour(1, SharedState(position=v, virtual=v))])
        assert not s._unmasked, f"stuck at {0.5 * k} s"
        target = np.array([*d.details.real_target, 0.0])
        steps.append(float(np.hypot(*(target - pose)[:2])))
        pose = target  # the robot arrives at each target
        path.append(pose[:2])
    # After the first spread, the robot gets less than STUCK_DISTANCE further in any
    # STUCK_TIME (the old rule's stuck) while it keeps taking new targets.
    window = int(STUCK_TIME / 0.5) + 1
    P = np.array(path[4:])
    assert max(np.hypot(*(P[k + window] - P[k])) for k in range(len(P) - window)) \
        < STUCK_DISTANCE
    assert (np.array(steps[4:]) > tol).sum() >= 10


def test_virtual_generator_moves_straight_through_obstacles_and_is_published():
    spec, domain = _world([0, 0, 6, 4], [{"type": "box", "center": [3.0, 2.0],
                                           "size": [0.4, 3.0]}])
    s = make_strategy("tangentbug", StrategyContext(domain=domain, robot=ROBOT))
    pose = np.array([1.0, 2.0, 0.0])
    other = Neighbour(1, SharedState(position=np.array([1.0, 3.5]),
                                     virtual=np.array([5.5, 2.0])))
    scan = simulate_scan(spec.grid, pose, ROBOT.lidar)
    d0 = s.update(Observation(0, pose, 10.0, scan), [other])
    # The cell is built against the neighbour's *virtual* generator, not its position.
    cell = euclidean_cell(domain, Generator(pose[:2]), [Generator(np.array([5.5, 2.0]))])
    np.testing.assert_allclose(d0.details.virtual_target, cell.centroid)
    assert d0.mass == pytest.approx(cell.mass) and d0.details.partition == "virtual"
    # A second later the virtual generator has moved v_max * 1 s straight toward its target,
    # although the wall is in the way; the robot itself is steered by TangentBug.
    d1 = s.update(Observation(0, pose, 11.0, scan), [other])
    u = cell.centroid - pose[:2]
    u /= np.hypot(*u)
    np.testing.assert_allclose(d1.shared.virtual, pose[:2] + ROBOT.v_max * u, atol=1e-12)
    assert d1.velocity is not None and d1.goal is None
    assert d1.shared.extra["cost_virtual"] == d1.details.cost_virtual
    # Without a scan the robot holds still (and says so).
    d2 = s.update(Observation(0, pose, 12.0, None), [other])
    assert d2.velocity == (0.0, 0.0)


def test_remembered_loop_projects_later_targets_without_circling():
    """A completed loop is remembered: a later virtual target behind it is projected onto it
    at once (the closest point of the loop), the robot does not circle the obstacle again."""
    spec, domain = _world([0, 0, 6, 4], [{"type": "circle", "center": [3.3, 2.0],
                                           "radius": 0.6}])
    s = make_strategy("tangentbug", StrategyContext(domain=domain, robot=ROBOT))
    centre, radius = np.array([3.3, 2.0]), 0.6 + CLEARANCE
    a = np.linspace(0.0, 2.0 * math.pi, 200, endpoint=False)
    s.loops.append((centre + radius * np.stack([np.cos(a), np.sin(a)], axis=-1), 1))
    pose = np.array([5.0, 3.0, 0.0])
    d = s.update(Observation(0, pose, 0.0, simulate_scan(spec.grid, pose, ROBOT.lidar)), [])
    target = np.asarray(d.details.virtual_target)  # the room's centroid, inside the circle
    assert np.hypot(*(target - centre)) < 0.6
    real = np.asarray(d.details.real_target)
    assert d.details.projected and d.mode == BugMode.MOTION_TO_GOAL.value
    loop = s.loops[0][0]
    assert np.hypot(*(real - target)) <= np.hypot(*(loop - target).T).min() + 1e-12
    u = (target - centre) / np.hypot(*(target - centre))
    np.testing.assert_allclose(real, centre + radius * u, atol=radius * a[1])  # polygon sides


def test_a_found_projection_is_kept_at_convergence():
    """Found by the Breitenmoser benchmark (Fig. 2b, one robot): after its loop the robot
    stopped at a projection it found, a few centimetres (> the tolerance) from the closest
    point of the remembered loop's polyline to the target - a point in the band its
    clearance keeps it out of. Taking that point as the real target at every Lloyd update
    re-projected the robot on the spot each time and it never converged. At Lloyd
    convergence (the virtual target moved less than the tolerance) a found projection is
    kept, and the robot standing at it has converged."""
    _, domain = _world([0, 0, 6, 4], [{"type": "circle", "center": [3.3, 2.0],
                                           "radius": 0.6}])
    s = make_strategy("tangentbug", StrategyContext(domain=domain, robot=ROBOT))
    centre, radius = np.array([3.3, 2.0]), 0.6 + CLEARANCE
    a = np.linspace(0.0, 2.0 * math.pi, 200, endpoint=False)
    s.loops.append((centre + radius * np.stack([np.cos(a), np.sin(a)], axis=-1), 1))
    target = np.array([3.0, 2.0])  # the room's centroid, inside the circle
    q = closest_on_polyline(s.loops[0][0], target)  # (3.3 - radius, 2.0)
    turn = 0.08 / radius  # [rad] 8 cm along the contour from q: farther than TOL
    x = centre + radius * np.array([-math.cos(turn), math.sin(turn)])
    s.virtual = s.virtual_target = target.copy()
    s.real_target, s.projected, s._projection_of = x.copy(), True, target.copy()
    s.bug.reset(x)
    s.bug.mode = BugMode.PROJECTED
    s._next_targets(x, target + np.array([0.01, 0.0]))  # a Lloyd step under the tolerance
    assert np.hypot(*(q - x)) > TOL
    np.testing.assert_allclose(s.real_target, x)
    assert s.converged and s.projected and s.bug.done
    # Lloyd steps under the tolerance that add up beyond it (the Fig. 4 benchmark's creeping
    # target) are followed: the projection is kept against the target it was found for.
    for k, creep in enumerate((0.03, 0.06)):
        s.virtual = s.virtual_target
        s._next_targets(x, target + np.array([0.0, creep]))
        assert s.converged == (k == 0)
    np.testing.assert_allclose(s.real_target,
                               closest_on_polyline(s.loops[0][0], s.virtual_target))
    assert not s.bug.done


def test_target_inside_a_free_standing_obstacle_is_projected_to_its_boundary():
    """Fig. 4 with one robot: the centroid of the room lies inside the obstacle; the robot
    circles it once and settles at the closest boundary point. With a single cell the real and
    virtual costs differ by exactly M |p - t|^2 (parallel axis theorem)."""
    spec, domain = _world([0, 0, 6, 4], [{"type": "circle", "center": [3.3, 2.0],
                                           "radius": 0.6}])
    res = _team(domain, [[5.4, 3.4, 0.0]], max_iterations=200)
    assert res.converged
    d = res.decisions[0]
    w = domain.mass_element.ravel()
    X, Y = domain.geometry.all_cell_centers()
    q = np.stack([X.ravel(), Y.ravel()], axis=-1)
    centroid = (q * w[:, None]).sum(axis=0) / w.sum()
    np.testing.assert_allclose(d.details.virtual_generator, centroid, atol=1e-9)
    assert not domain.is_free_point(centroid)  # inside the obstacle
    assert d.details.projected and d.details.known_loops == 1 and d.details.partition == "real"
    ref = _projection_reference(spec.grid, centroid, CLEARANCE)
    real = np.asarray(d.details.real_target)
    assert np.hypot(*(real - centroid)) == pytest.approx(
        np.hypot(*(ref - centroid)), abs=SCAN_BIAS + REF_RES + TRACKING)
    p = res.positions[-1, 0]
    assert np.hypot(*(p - real)) <= TOL
    mass = float(w.sum())
    assert d.cost - d.details.cost_virtual == pytest.approx(
        mass * float(((p - centroid) ** 2).sum()), rel=1e-9)


def test_two_robots_fig4_cost_bounds():
    """Breitenmoser et al. 2010, Remark 1: H(t_virt, V) <= H(p*, V_end) <= H(p*, V) - the final
    repartition on the real positions can only lower the cost of the projected configuration."""
    spec, domain = _world([0, 0, 8, 4], [{"type": "circle", "center": [2.1, 2.0],
                                           "radius": 0.6}])
    res = _team(domain, [[0.6, 0.6, 0.0], [7.4, 3.4, math.pi]], max_iterations=250)
    assert res.converged
    left, right = res.decisions
    assert left.details.projected and not right.details.projected
    V = np.array([d.details.virtual_generator for d in res.decisions])
    P = res.positions[-1]
    assert not domain.is_free_point(V[0])  # the left target is inside the obstacle
    assert np.hypot(*(P[1] - V[1])) <= TOL  # the right one was reached
    h_real, h_virt = team_costs(domain, P, V)
    assert (h_real, h_virt) == pytest.approx(decision_costs(res.decisions), rel=1e-9)
    assert h_virt <= h_real <= _labels_cost(domain, V, P) + 1e-9
    ref = _projection_reference(spec.grid, V[0], CLEARANCE)
    assert np.hypot(*(left.details.real_target - V[0])) == pytest.approx(
        np.hypot(*(ref - V[0])), abs=SCAN_BIAS + REF_RES + TRACKING)


@pytest.mark.slow
def test_u_world_five_robots_converge_and_real_cost_meets_virtual_cost():
    """Fig. 3: five robots from a corner of the U-shaped world. TangentBug takes them round
    the block; at convergence every target is free and reached, and the real cost is the
    virtual one up to the arrival tolerance: H_real - H_virt <= sum_i M_i |p_i - c_i|^2 with
    |p_i - c_i| <= |p_i - g_i| + |g_i - c_i| <= 2 TOL (parallel axis theorem)."""
    spec = load_world(WORLDS / "u_shape.yaml")
    domain = CoverageDomain.from_grid(spec.grid, ROBOT.radius, spec.density)
    starts = np.array([[s.x, s.y, s.yaw] for s in spec.starts])
    res = _team(domain, starts, max_iterations=400)
    assert res.converged
    P = res.positions[-1]
    V = np.array([d.details.virtual_generator for d in res.decisions])
    assert all(domain.is_free_point(v) for v in V)
    assert np.hypot(*(P - V).T).max() <= TOL
    assert (P[:, 0] > 6.5).sum() >= 2  # robots went round the block into the right arm
    h_real, h_virt = decision_costs(res.decisions)
    assert res.costs[-1] == pytest.approx(h_real)
    assert h_real == pytest.approx(euclidean_cost(domain, [Generator(p) for p in P]))
    mass = float(domain.mass_element.sum())
    assert abs(h_real - h_virt) <= mass * (2 * TOL) ** 2
    assert h_real < 0.1 * res.costs[0]  # from a clustered start to a spread team
