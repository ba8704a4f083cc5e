"""Local navigation: planning, tracking within limits, and the safety filter."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from conftest import WORLDS

from coverage_ros.core.control.controller import ControllerConfig, RobotController
from coverage_ros.core.control.neighbours import NeighbourTable, safety_discs
from coverage_ros.core.control.planning import plan_path, segment_free
from coverage_ros.core.control.safety import MEMORY_RADIUS, SafetyConfig, SafetyFilter, ScanMemory
from coverage_ros.core.control.tracking import PathTracker, TrackerConfig
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies import Neighbour, Scan, SharedState
from coverage_ros.core.world import RobotSpec, load_world
from coverage_ros.core.world.grid import OCCUPIED, GridMap

RES = 0.05
RADIUS = 0.105


def room(wall=True) -> CoverageDomain:
    """4 m x 3 m room; with a wall across x = 2 m from y = 0 to y = 2.2 m."""
    occ = np.zeros((60, 80), np.int8)
    occ[0, :] = occ[-1, :] = OCCUPIED
    occ[:, 0] = occ[:, -1] = OCCUPIED
    if wall:
        occ[:44, 39:41] = OCCUPIED
    return CoverageDomain.from_grid(GridMap(occ, RES), RADIUS)


def drive(pose, v, w, dt):
    x, y, th = pose
    return np.array([x + v * dt * math.cos(th + 0.5 * w * dt),
                     y + v * dt * math.sin(th + 0.5 * w * dt), th + w * dt])


def test_plan_goes_around_the_wall_and_stays_free():
    d = room()
    path = plan_path(d, np.array([1.0, 0.5]), np.array([3.0, 0.5]))
    assert path is not None and len(path) >= 3
    assert path[:, 1].max() > 2.2  # over the end of the wall
    for a, b in itertools.pairwise(path):
        assert segment_free(d, a, b)
    length = np.hypot(*np.diff(path, axis=0).T).sum()
    assert length < 1.15 * (2 * math.hypot(1.0, 1.9))  # close to the shortest way round


def test_straight_path_when_free_and_none_when_unreachable():
    d = room()
    assert plan_path(d, np.array([0.5, 0.5]), np.array([1.5, 2.5])).shape == (2, 2)
    occ = np.zeros((40, 40), np.int8)
    occ[:, 20] = OCCUPIED  # a wall all the way across
    closed = CoverageDomain.from_grid(GridMap(occ, RES), RADIUS)
    assert plan_path(closed, np.array([0.3, 1.0]), np.array([1.7, 1.0])) is None


def hall(gap_from: float = 5.5) -> CoverageDomain:
    """6 m x 6 m hall split by a wall across x = 3 m from y = 0 up to ``gap_from`` [m]."""
    occ = np.zeros((120, 120), np.int8)
    occ[0, :] = occ[-1, :] = OCCUPIED
    occ[:, 0] = occ[:, -1] = OCCUPIED
    occ[:int(round(gap_from / RES)), 59:61] = OCCUPIED
    return CoverageDomain.from_grid(GridMap(occ, RES), RADIUS)


def test_a_goal_far_round_a_wall_is_planned_for_only_without_the_detour_limit():
    """0.6 m apart in a straight line, ~10 m round the wall: beyond the default detour (4 x
    + 2 m), planned with an infinite one; a goal no path reaches is None either way."""
    d, a, b = hall(), np.array([2.7, 0.5]), np.array([3.3, 0.5])
    assert plan_path(d, a, b) is None
    path = plan_path(d, a, b, max_detour=math.inf)
    assert path is not None and path[:, 1].max() > 5.5  # through the gap at the top
    assert np.allclose(path[0], a) and np.allclose(path[-1], b)
    for p, q in itertools.pairwise(path):
        assert segment_free(d, p, q)
    length = np.hypot(*np.diff(path, axis=0).T).sum()
    assert 2 * math.hypot(0.3, 5.0) < length < 1.1 * 2 * math.hypot(0.3, 5.5)
    assert plan_path(hall(gap_from=6.0), a, b, max_detour=math.inf) is None  # (closed)


def test_a_destination_on_another_part_of_the_map_is_refused_without_a_whole_map_search(
        monkeypatch):
    """A goal no path can reach gets None without a search of the whole map when the detour
    is unlimited (a robot would otherwise search its whole side of the map at every update);
    across an open gap it is planned, over the whole map."""
    import coverage_ros.core.control.planning as planning

    windows = []
    graph = planning._planning_graph

    def recorded(domain, start, goal, margin):
        windows.append(margin)
        return graph(domain, start, goal, margin)

    monkeypatch.setattr(planning, "_planning_graph", recorded)
    a, b = np.array([2.7, 0.5]), np.array([3.3, 0.5])
    assert plan_path(hall(gap_from=6.0), a, b, max_detour=math.inf) is None
    assert None not in windows
    assert plan_path(hall(), a, b, max_detour=math.inf) is not None
    assert windows[-1] is None


def test_a_destination_far_round_takes_the_maps_shortest_way_not_the_windows():
    """The first search covers the box of start and goal (+ 2 m): a way through it that winds
    past baffles is longer than the default detour, while the map's shortest way runs through
    a gap outside the box; the path planned without the detour limit is that shortest one,
    as with the default detour."""
    occ = np.zeros((240, 240), np.int8)
    occ[0, :] = occ[-1, :] = OCCUPIED
    occ[:, 0] = occ[:, -1] = OCCUPIED

    def cells(v: float) -> int:
        return int(round(v / RES))

    occ[:, cells(3.0):cells(3.1)] = OCCUPIED  # a wall at x = 3 m with two gaps:
    occ[cells(8.5):cells(9.1), cells(3.0):cells(3.1)] = 0  # one outside the box,
    occ[cells(4.3):cells(4.9), cells(3.0):cells(3.1)] = 0  # one inside, behind baffles
    occ[cells(5.5):cells(5.6), cells(0.6):cells(3.0)] = OCCUPIED
    for i, x in enumerate(np.arange(0.9, 2.9, 0.4)):
        rows = slice(cells(4.25), cells(5.5)) if i % 2 == 0 else slice(cells(2.0), cells(5.25))
        occ[rows, cells(x):cells(x + 0.1)] = OCCUPIED
    d = CoverageDomain.from_grid(GridMap(occ, RES), RADIUS)
    a, b = np.array([2.0, 6.0]), np.array([4.0, 6.0])

    def length(path: np.ndarray) -> float:
        return float(np.hypot(*np.diff(path, axis=0).T).sum())

    far, windowed = plan_path(d, a, b, max_detour=math.inf), plan_path(d, a, b)
    assert far is not None and windowed is not None
    assert far[:, 1].max() > 8.5  # through the gap outside the box
    assert length(far) < 2 * math.hypot(1.0, 3.0) + 0.5
    assert length(far) == pytest.approx(length(windowed), rel=1e-9)
    for p, q in itertools.pairwise(far):
        assert segment_free(d, p, q)


class _Fixed:
    """A strategy whose decisions are another's with the goal and mode given."""

    def __init__(self, strategy, goal: np.ndarray, mode: str) -> None:
        self._strategy, self._goal, self._mode = strategy, goal, mode

    def update(self, obs, nbrs):
        import dataclasses

        d = self._strategy.update(obs, nbrs)
        return dataclasses.replace(d, goal=self._goal, target=self._goal, mode=self._mode)

    def __getattr__(self, name):
        return getattr(self._strategy, name)


@pytest.mark.parametrize("mode", ["relocate", "seek", "lloyd"])
def test_a_destination_far_round_a_wall_gets_a_path_a_step_of_the_own_cell_does_not(mode):
    """A relocation to a claimed cell or a region's nearest point is planned for however far
    round the wall the way goes (a robot shut in a room off another corridor than its target
    stood still until its move timed out); a Lloyd goal keeps the detour limit."""
    from coverage_ros.core.strategies import strategy_choice

    c = RobotController(hall(), ControllerConfig(robot_id=0, strategy=strategy_choice("lloyd")))
    c.strategy = _Fixed(c.strategy, np.array([3.3, 0.5]), mode)
    c.set_pose((2.7, 0.5, 0.0))
    path = c.update(0.0).path
    if mode == "lloyd":
        assert path is None
    else:
        assert path is not None and path[:, 1].max() > 5.5 and np.allclose(path[-1], [3.3, 0.5])


def test_tracker_reaches_the_goal_within_the_limits():
    d = room()
    spec = RobotSpec()
    tracker = PathTracker(TrackerConfig.for_robot(spec))
    path = plan_path(d, np.array([1.0, 0.5]), np.array([3.0, 0.5]))
    pose, dt = np.array([1.0, 0.5, -math.pi / 2]), 0.1
    v_prev = w_prev = 0.0
    for _ in range(600):
        v, w, arrived = tracker.command(pose, path, dt)
        assert abs(v) <= spec.v_max + 1e-9 and abs(w) <= spec.w_max + 1e-9
        assert abs(v - v_prev) <= spec.a_max * dt + 1e-9
        assert abs(w - w_prev) <= spec.alpha_max * dt + 1e-9
        v_prev, w_prev = v, w
        if arrived:
            break
        pose = drive(pose, v, w, dt)
        r, c = d.geometry.world_to_cell(pose[:2])
        assert d.clearance[r, c] > RADIUS + 0.5 * RES, "the body came within half a cell"
    assert arrived and np.hypot(*(pose[:2] - path[-1])) < 0.06


def test_safety_filter_stops_before_a_wall_but_lets_the_robot_turn_and_back_off():
    d = room()
    f = SafetyFilter(d, SafetyConfig(radius=RADIUS))
    at_wall = np.array([1.8, 1.0, 0.0])  # facing the wall at x = 1.95, 0.15 m ahead
    v, w, why = f.filter(at_wall, 0.22, 0.3)
    assert v < 0.22 and "wall" in why
    # Moving away is always allowed, even from inside the inflated zone.
    inside = np.array([1.86, 1.0, math.pi])
    assert f.filter(inside, 0.22, 0.0)[0] == pytest.approx(0.22)
    assert f.filter(inside, 0.0, 1.0)[:2] == (0.0, 1.0)
    # Simulated: full speed at the wall never enters it.
    pose = np.array([1.0, 1.0, 0.0])
    for _ in range(100):
        v, w, _ = f.filter(pose, 0.22, 0.0)
        pose = drive(pose, v, w, 0.1)
    assert pose[0] + RADIUS < 1.95


def test_safety_filter_keeps_robots_apart():
    d = room(wall=False)
    f = SafetyFilter(d, SafetyConfig(radius=RADIUS))
    a, b = np.array([1.0, 1.5, 0.0]), np.array([1.5, 1.5, math.pi])
    for _ in range(100):  # head-on, both commanded at full speed
        va, wa, _ = f.filter(a, 0.22, 0.0, b[None, :2])
        vb, wb, _ = f.filter(b, 0.22, 0.0, a[None, :2])
        a, b = drive(a, va, wa, 0.1), drive(b, vb, wb, 0.1)
    assert np.hypot(*(a[:2] - b[:2])) >= 2 * RADIUS + 0.02
    # Sideways past a neighbour is fine.
    assert f.filter(np.array([1.0, 1.0, 0.0]), 0.22, 0.0, np.array([[1.0, 1.4]]))[0] == 0.22


def _side_by_side(publish_velocity: bool) -> float:
    """Two robots 0.3 m apart at 0.4 m/s on headings 4 degrees apart, closing at 3 cm/s (the
    live Lee & Lee Fig. 17a-c contact): each filters its command every 0.1 s against the
    other's state as safety_discs makes of it - published every 0.4 s with a pose a tick old
    (odometry comes at 10 Hz). The least distance between them."""
    occ = np.zeros((80, 240), np.int8)
    occ[0, :] = occ[-1, :] = OCCUPIED
    occ[:, 0] = occ[:, -1] = OCCUPIED
    f = SafetyFilter(CoverageDomain.from_grid(GridMap(occ, RES), RADIUS),
                     SafetyConfig(radius=RADIUS))
    spec = RobotSpec(radius=RADIUS, v_max=0.4)
    poses = [np.array([1.1, 2.21, math.radians(-20.7)]),
             np.array([1.0, 1.92, math.radians(-16.6)])]
    last, sent, heard = [p.copy() for p in poses], [0.0, 0.0], [None, None]
    least = math.inf
    for k in range(150):
        now = 0.1 * k
        if k % 4 == 0:  # states at 2.5 Hz
            for i in range(2):
                v = sent[i] * np.array([math.cos(last[i][2]), math.sin(last[i][2])])
                extra = {"vx": v[0], "vy": v[1]} if publish_velocity else {}
                heard[1 - i] = Neighbour(i, SharedState(last[i][:2].copy(), extra=extra), now)
        for i in range(2):
            pos, radii, vel = safety_discs([heard[i]], now, spec)
            sent[i] = f.filter(poses[i], 0.4, 0.0, pos, radii, None, vel)[0]
        last = poses
        poses = [drive(poses[i], sent[i], 0.0, 0.1) for i in range(2)]
        least = min(least, float(np.hypot(*(poses[0][:2] - poses[1][:2]))))
    return least


def test_safety_filter_keeps_robots_on_converging_headings_apart():
    """Checked only where a neighbour is (where it last published, grown by v_max x the age),
    each sees the other fall behind its own arc: they touch (least distance below 0.21 m).
    With the published velocities each also checks where the other will be."""
    assert _side_by_side(publish_velocity=True) >= 2 * RADIUS + 0.03


def test_safety_filter_uses_scan_points():
    d = room(wall=False)
    f = SafetyFilter(d, SafetyConfig(radius=RADIUS))
    box = np.array([[1.2, y] for y in np.linspace(0.8, 1.2, 9)])  # not on the map, 9.5 cm ahead
    assert f.filter(np.array([1.0, 1.0, 0.0]), 0.22, 0.0, scan_points=box)[0] < 0.22
    assert f.filter(np.array([1.0, 1.0, math.pi]), 0.22, 0.0, scan_points=box)[0] == 0.22


def box_scan(pose, face=(1.2, 0.8, 1.2), beams=360, range_min=0.12):
    """A 360-beam scan of a box's face x = x0, y0 <= y <= y1 (x0, y0, y1) in free space, REP
    117: -inf nearer than range_min, +inf where a beam misses it."""
    x0, y0, y1 = face
    a = pose[2] - math.pi + 2 * math.pi / beams * np.arange(beams)
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(c > 0, (x0 - pose[0]) / c, np.inf)  # the box's near face
        hit_y = pose[1] + tx * s
    r = np.where((tx > 0) & (hit_y >= y0) & (hit_y <= y1), tx, np.inf)
    r = np.where(r < range_min, -np.inf, r)
    return Scan(ranges=r, angle_min=-math.pi, angle_increment=2 * math.pi / beams,
                range_min=range_min, range_max=3.5)


def test_an_obstacle_the_lidar_no_longer_sees_stays_in_the_safety_filter():
    """A lidar sees nothing nearer than range_min (0.12 m; the body reaches 0.105 m): a robot
    creeping at a box not on the map loses it from the scan just before contact. Its points
    stay (ScanMemory) until a beam passes beyond them."""
    d = room(wall=False)
    f = SafetyFilter(d, SafetyConfig(radius=RADIUS))
    memory = ScanMemory()
    pose = np.array([0.9, 1.0, 0.0])  # the box's face is at x = 1.2
    for _ in range(200):
        scan = box_scan(pose)
        points = memory.update(scan, pose, scan.points(pose))
        v, w, _ = f.filter(pose, 0.05, 0.0, scan_points=points)
        pose = drive(pose, v, w, 0.1)
    assert 1.2 - pose[0] >= RADIUS  # never touched it
    assert np.all(np.isneginf(box_scan(pose).ranges[175:186]))  # though it sees nothing there
    # Without the memory the same creep ends inside the box's face.
    pose = np.array([0.9, 1.0, 0.0])
    for _ in range(200):
        scan = box_scan(pose)
        v, w, _ = f.filter(pose, 0.05, 0.0, scan_points=scan.points(pose))
        pose = drive(pose, v, w, 0.1)
    assert 1.2 - pose[0] < RADIUS
    # What moved away is forgotten once a beam passes beyond it; what is far is dropped.
    scan = box_scan(np.array([0.9, 1.0, 0.0]))
    memory = ScanMemory()
    assert len(memory.update(scan, np.array([0.9, 1.0, 0.0]), scan.points((0.9, 1.0, 0.0))))
    empty = box_scan(np.array([0.9, 1.0, 0.0]), face=(5.0, 0.8, 1.2))
    assert len(memory.update(empty, np.array([0.9, 1.0, 0.0]), np.zeros((0, 2)))) == 0
    memory.update(scan, np.array([0.9, 1.0, 0.0]), scan.points((0.9, 1.0, 0.0)))
    far = np.array([0.9 - MEMORY_RADIUS - 0.4, 1.0, 0.0])
    assert len(memory.update(box_scan(far), far, np.zeros((0, 2)))) == 0


def test_a_wall_seen_again_and_again_is_no_nearer_in_the_memory_than_in_the_newest_scan():
    """Scans placed from a slightly wrong pose (a turning robot's stamp a few ms off) put a
    wall's points a little off it, some nearer the robot: the memory keeps only the newest
    scan's points in every direction a beam measured, so they do not pile up into a wall nearer
    than the real one that blocks a robot with room to pass (1.5 cm to spare beside a pillar)."""
    d = room(wall=False)
    f = SafetyFilter(d, SafetyConfig(radius=RADIUS))
    memory = ScanMemory()
    face = (1.2, 0.5, 1.5)
    pose = np.array([1.2 - RADIUS - 0.015, 0.9, math.pi / 2])  # heading along the face
    rng = np.random.default_rng(3)
    for err in rng.uniform(-0.12, 0.12, 40):  # [rad] where each scan is placed
        placed = pose + np.array([0.0, 0.0, err])
        scan = box_scan(pose, face=face)
        memory.update(scan, placed, scan.points(placed))
    scan = box_scan(pose, face=face)
    points = memory.update(scan, pose, scan.points(pose))
    assert len(points) and np.all(points[:, 0] >= 1.2 - 1e-9)
    v, _, why = f.filter(pose, 0.22, 0.0, scan_points=points)
    assert v == 0.22, why
    # Points nearer than the face would have stopped it.
    ghost = np.array([[1.2 - 0.02, 1.0]])
    assert f.filter(pose, 0.22, 0.0, scan_points=np.vstack([points, ghost]))[0] < 0.22


def test_a_late_pose_is_carried_forward_under_the_last_command_before_the_safety_check():
    """A busy robot process reads its pose late: the tracker and the safety filter work from
    the pose carried forward to now under the last command (else a robot driving at a box
    checks its command from where it was, 8 cm back)."""
    c = RobotController(room(wall=False), ControllerConfig(robot_id=0))
    c.path = np.array([[1.0, 1.0], [3.0, 1.0]])
    c.scan_points = np.array([[1.30, y] for y in np.linspace(0.8, 1.2, 9)])  # a box's face
    c.set_pose((1.0, 1.0, 0.0), stamp=10.0)
    c.tracker.override(0.22, 0.0)
    assert c.command(10.0, 0.1)[0] == pytest.approx(0.22)  # from x = 1.0 the box is far enough
    c.tracker.override(0.22, 0.0)
    assert c.command(10.4, 0.1)[0] < 0.22  # 0.4 s later the robot is at x = 1.09
    assert "slowed" in c.safety_note
    assert "max 400 ms" in c.describe_pose_age()
    # Carried forward by at most MAX_POSE_AGE; a pose without a stamp is taken as now.
    c.set_pose((1.0, 1.0, 0.0))
    c.tracker.override(0.22, 0.0)
    assert c.command(99.0, 0.1)[0] == pytest.approx(0.22)


def test_a_scan_before_the_first_pose_is_kept_and_its_points_wait_for_a_pose():
    c = RobotController(room(wall=False), ControllerConfig(robot_id=0))
    scan = Scan(np.full(8, 0.3), 0.0, 2.0 * math.pi / 8, 0.1, 3.5)  # within MEMORY_RADIUS
    c.set_scan(scan, scan.points(np.array([1.0, 1.0, 0.0])))
    assert c.scan is scan and c.scan_pose is None and c.scan_points is None
    c.set_pose((1.0, 1.0, 0.0))
    c.set_scan(scan, scan.points(np.array([1.0, 1.0, 0.0])))
    assert c.scan_points is not None and len(c.scan_points) == 8


def test_neighbour_table_validates_and_expires():
    t = NeighbourTable((0.0, 0.0, 4.0, 3.0), timeout=2.0)
    assert t.receive(1, {"x": 1.0, "y": 1.0, "weight": 0.2, "mass": 3.0}, now=10.0) == ""
    assert "outside the map" in t.receive(2, {"x": 9.0, "y": 1.0}, now=10.0)
    assert "nan" in t.receive(3, {"x": 1.0, "y": 1.0, "mass": float("nan")}, now=10.0)
    assert "weight" in t.receive(4, {"x": 1.0, "y": 1.0, "weight": -1.0}, now=10.0)
    assert [n.robot_id for n in t.current(11.0)] == [1]
    assert t.current(12.5) == []  # stale
    t.receive(5, {"x": 3.5, "y": 2.5, "virtual_x": 1.0, "virtual_y": 2.0, "radius": 0.2}, 13.0)
    n5 = t.current(13.0)[0]
    assert np.allclose(n5.state.virtual, [1.0, 2.0]) and n5.state.extra["radius"] == 0.2
    assert t.current(13.0, own=np.array([0.5, 0.5]), comm_range=1.0) == []


def test_robots_of_one_process_share_a_neighbours_state_checked_once_per_map():
    """The state hub passes one ``parsed`` dict per message: tables with the same map extent
    get the same (read-only) state, a table with another extent checks the values itself."""
    a, b = (NeighbourTable((0.0, 0.0, 4.0, 3.0), timeout=2.0) for _ in range(2))
    small = NeighbourTable((0.0, 0.0, 2.0, 2.0), timeout=2.0)
    parsed: dict = {}
    values = {"x": 3.0, "y": 1.0, "weight": 0.1}
    assert a.receive(7, values, 1.0, parsed) == b.receive(7, values, 1.5, parsed) == ""
    assert "outside the map" in small.receive(7, values, 1.0, parsed)
    assert len(parsed) == 2
    sa, sb = a.current(1.5)[0], b.current(1.5)[0]
    assert sa.state is sb.state and sa.stamp == 1.0 and sb.stamp == 1.5
    with pytest.raises(ValueError):
        sa.state.position[0] = 0.0  # shared: read-only
    assert small.current(1.0) == []


def test_controller_update_and_command():
    d = room()
    c = RobotController(d, ControllerConfig(robot_id=0))
    assert c.update(0.0) is None  # no pose yet
    c.set_pose((1.0, 1.0, 0.0))
    c.neighbours.receive(1, {"x": 3.0, "y": 1.0}, now=0.0)
    res = c.update(0.5)
    assert res.neighbours == [1]
    assert set(res.state) >= {"x", "y", "weight", "mass", "cost", "update_ms", "radius"}
    assert res.decision.goal is not None and res.path is not None
    v, w = c.command(0.6, 0.1)
    assert abs(v) <= 0.22 and abs(w) <= 2.84



def _drive_until_still(c: RobotController, pose: np.ndarray, t: float, seconds: float
                       ) -> tuple[np.ndarray, float]:
    """Drive ``c``'s robot by its own commands (a perfect unicycle at 10 Hz) for ``seconds``."""
    from coverage_ros.core.control.safety import unicycle

    for _ in range(int(seconds * 10)):
        v, w = c.command(t, 0.1)
        pose = unicycle(pose, v, w, np.array([0.1]))[0]
        t += 0.1
        c.set_pose(tuple(pose))
    return pose, t


class _Shifted:
    """A strategy whose goals are another's, shifted by ``offset``."""

    def __init__(self, strategy, offset: np.ndarray) -> None:
        self._strategy, self._offset = strategy, offset

    def update(self, obs, nbrs):
        import dataclasses

        d = self._strategy.update(obs, nbrs)
        return dataclasses.replace(d, goal=np.asarray(d.goal) + self._offset)

    def __getattr__(self, name):
        return getattr(self._strategy, name)


@pytest.mark.parametrize("arrival", [0.02, 0.05])
def test_a_robot_stops_within_its_arrival_tolerance_and_follows_a_goal_that_creeps(arrival):
    """The tracker stops ``arrival_tolerance`` short of the goal at most; a robot standing at
    its goal follows a new goal ``arrival_tolerance`` away or more (a Lloyd goal creeps a few
    cm per update near the end) and keeps still for a nearer one: with the old 5 cm a live
    team stopped short of Lloyd's last steps (Lee & Lee's Fig. 17a-c)."""
    from coverage_ros.core.strategies import strategy_choice

    c = RobotController(room(wall=False), ControllerConfig(
        robot_id=0, strategy=strategy_choice("lloyd"), arrival_tolerance=arrival))
    pose = np.array([1.0, 1.0, 0.0])
    c.set_pose(tuple(pose))
    goal = c.update(0.0).decision.goal
    pose, t = _drive_until_still(c, pose, 0.0, 20.0)
    gap = float(np.hypot(*(goal - pose[:2])))
    assert gap < arrival and c.command(t, 0.1)[0] == 0.0
    # The goal creeps to 3.5 cm from the robot, off to its side (as a neighbour moving a
    # little would make it): followed with 2 cm, not with 5 cm.
    side = np.array([-(goal - pose[:2])[1], (goal - pose[:2])[0]]) / gap
    c.strategy = _Shifted(c.strategy, pose[:2] + 0.035 * side - goal)
    new = c.update(t).decision.goal
    assert float(np.hypot(*(new - pose[:2]))) == pytest.approx(0.035)
    moved_to, t = _drive_until_still(c, pose, t, 10.0)
    step = float(np.hypot(*(moved_to[:2] - pose[:2])))
    if arrival < 0.035:
        assert float(np.hypot(*(new - moved_to[:2]))) < arrival and step > 0.01
    else:
        assert step == 0.0  # within the tolerance: it keeps still


def test_a_region_of_interest_moves_the_goal_into_it_and_clearing_it_moves_it_back():
    """A lone robot's goal is its cell's centroid: the room's middle, then the middle of the
    region once the density is kept inside it, then the room's middle again."""
    from coverage_ros.core.strategies import strategy_choice
    from coverage_ros.core.world.region import Region
    from coverage_ros.errors import ConfigError

    d = room(wall=False)
    c = RobotController(d, ControllerConfig(robot_id=0, strategy=strategy_choice("lloyd")))
    c.set_pose((1.0, 1.0, 0.0))
    whole = c.update(0.0).decision.goal
    assert whole == pytest.approx([2.0, 1.5], abs=0.1)
    region = Region().with_polygon([[2.8, 1.8], [3.6, 1.8], [3.6, 2.6], [2.8, 2.6]])
    c.set_region(region)
    assert c.goal is None and c.path is None  # replans
    inside = c.update(1.0).decision.goal
    assert inside == pytest.approx([3.2, 2.2], abs=0.05)
    assert c.domain.density[d.free].sum() < 0.1 * d.density[d.free].sum()
    with pytest.raises(ConfigError, match="no free space"):
        c.set_region(Region().with_polygon([[10, 10], [11, 10], [11, 11]]))
    assert c.region is region  # a refused region changes nothing
    c.set_region(Region())
    assert c.update(2.0).decision.goal == pytest.approx(whole, abs=1e-9)
    # A neighbour in the region takes all of it: this robot's cell holds none, and it heads
    # for the region's nearest point instead of staying where it is.
    c.set_region(region)
    c.neighbours.receive(1, {"x": 3.2, "y": 2.2}, now=3.0)
    seek = c.update(3.0).decision
    assert seek.mode == "seek" and not seek.converged
    assert seek.goal == pytest.approx([2.8, 1.8], abs=0.06)  # the square's nearest corner


def test_vectorized_shortcut_equals_the_segment_by_segment_greedy():
    """shortcut() checks candidates in batches; the result is the one-by-one greedy's."""
    from coverage_ros.core.control.planning import PATH_MARGIN, SHORTCUT_REACH, shortcut

    def slow(domain, path):
        out, i = [path[0]], 0
        while i < len(path) - 1:
            j = min(len(path) - 1, i + SHORTCUT_REACH)
            if j > i + 1 and not segment_free(domain, path[i], path[i + 2], PATH_MARGIN):
                j = i + 1
            while j > i + 1 and not segment_free(domain, path[i], path[j], PATH_MARGIN):
                j -= 1
            out.append(path[j])
            i = j
        return np.array(out)

    world = load_world(WORLDS / "office.yaml")
    domain = CoverageDomain.from_grid(world.grid, 0.105)
    rng = np.random.default_rng(7)
    free = np.argwhere(domain.free)
    for _ in range(10):
        a, b = domain.to_map(free[rng.integers(len(free), size=2)][:, ::-1] + 0.5)
        path = plan_path(domain, a, b)
        if path is None:
            continue
        # A dense path (every cell of a grid path) to shorten again.
        dense = np.vstack([np.linspace(p, q, 6, endpoint=False) for p, q in
                           itertools.pairwise(path)] + [path[-1:]])
        np.testing.assert_array_equal(shortcut(domain, dense), slow(domain, dense))



def test_a_self_steering_command_is_re_steered_towards_its_heading_between_updates():
    """A turn rate held for a whole coverage period overshoots (saturated, the robot spins):
    the tracking loop turns towards the strategy's heading instead."""
    c = RobotController(room(wall=False), ControllerConfig(robot_id=0))
    c.set_pose((1.0, 1.5, 0.0))
    c.velocity, c.heading = (0.2, 2.84), 0.3  # what the strategy decided at yaw 0
    v, w = c.command(0.0, 0.1)
    assert w == pytest.approx(2.5 * 0.3) and v == pytest.approx(0.2)
    c.set_pose((1.0, 1.5, 0.3))  # turned as far as wanted: stop turning
    assert c.command(0.1, 0.1)[1] == pytest.approx(0.0, abs=1e-9)
    c.set_pose((1.0, 1.5, 0.3 + 1.5))  # far off: turn back in place
    v, w = c.command(0.2, 0.1)
    assert v == 0.0 and w == pytest.approx(-2.84)
    c.heading = None  # no heading: the command is held as it is
    assert c.command(0.3, 0.1) == pytest.approx((0.2, 2.84))
