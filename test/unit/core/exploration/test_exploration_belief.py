"""The occupancy belief of exploration: the inverse sensor model against analytic rooms and a
slow reference, and the fusion of several robots' evidence without a map server."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coverage_ros.core.exploration.belief import Belief, BeliefConfig, Evidence, entropy
from coverage_ros.core.exploration.sensor_model import (
    ScanCells,
    footprint_cells,
    reference_scan_cells,
    scan_cells,
)
from coverage_ros.core.offline.rangesim import simulate_scan
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.robot import LidarSpec
from coverage_ros.errors import ConfigError

RES = 0.05
LIDAR = LidarSpec(beams=360, range_max=3.5)


def lattice(h: int = 120, w: int = 160) -> GridMap:
    return GridMap(np.full((h, w), -1, np.int8), RES)


def room_scan(pose, room=(0.0, 0.0, 4.0, 3.0)):
    """Analytic ranges in an empty axis-aligned room (walls at the room's sides)."""
    x0, y0, x1, y1 = room
    a = pose[2] + LIDAR.angle_min + LIDAR.angle_increment * np.arange(LIDAR.beams)
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(c > 0, (x1 - pose[0]) / c, np.where(c < 0, (x0 - pose[0]) / c, np.inf))
        ty = np.where(s > 0, (y1 - pose[1]) / s, np.where(s < 0, (y0 - pose[1]) / s, np.inf))
    r = np.minimum(tx, ty)
    return np.where(r <= LIDAR.range_max, r, np.inf)


def disc_scan(pose, centre, radius):
    """``room_scan`` with a disc (another robot's body) in the room."""
    a = pose[2] + LIDAR.angle_min + LIDAR.angle_increment * np.arange(LIDAR.beams)
    d = np.stack([np.cos(a), np.sin(a)], axis=-1)
    rel = np.asarray(centre) - pose[:2]
    along = d @ rel
    miss2 = rel @ rel - along ** 2
    with np.errstate(invalid="ignore"):
        t = along - np.sqrt(radius ** 2 - miss2)
    hit = (miss2 <= radius ** 2) & (t > 0)
    return np.where(hit, np.minimum(t, room_scan(pose)), room_scan(pose))


def cells_xy(lat: GridMap, idx: np.ndarray) -> np.ndarray:
    rows, cols = np.divmod(idx, lat.width)
    return lat.cell_centers(np.stack([rows, cols], axis=-1))


def test_cells_along_a_beam_are_free_the_hit_cell_occupied_and_nothing_behind():
    lat = lattice()
    pose = np.array([1.0, 1.5, 0.0])
    ranges = np.full(LIDAR.beams, -np.inf)  # every beam but one: nothing valid
    k = int(round((0.0 - LIDAR.angle_min) / LIDAR.angle_increment))  # the beam along +x
    ranges[k] = 2.0
    cells = scan_cells(lat, pose, ranges, LIDAR.angle_min, LIDAR.angle_increment,
                       LIDAR.range_min, LIDAR.range_max)
    free, occ = cells_xy(lat, cells.free), cells_xy(lat, cells.occupied)
    # The hit point (3.0, 1.5) lies on a cell border: the cell behind it is the obstacle's.
    np.testing.assert_allclose(occ, [[3.025, 1.525]])
    assert np.allclose(free[:, 1], 1.525)
    np.testing.assert_allclose(np.sort(free[:, 0]), 1.025 + RES * np.arange(40))
    assert free[:, 0].max() < 3.0  # nothing at or behind the hit is free


def test_an_empty_room_is_seen_as_it_is():
    """All walls of a room within range: every cell the model marks occupied is on a wall,
    every free cell inside, and the whole interior in sight is seen free."""
    lat = lattice()
    pose = np.array([2.0, 1.5, 0.4])
    cells = scan_cells(lat, pose, room_scan(pose), LIDAR.angle_min, LIDAR.angle_increment,
                       LIDAR.range_min, LIDAR.range_max)
    occ, free = cells_xy(lat, cells.occupied), cells_xy(lat, cells.free)
    on_wall = (np.abs(occ[:, 0] - 4.025) < 1e-9) | (np.abs(occ[:, 1] - 3.025) < 1e-9) | \
        (np.abs(occ[:, 0] + 0.025) < 1e-9) | (np.abs(occ[:, 1] + 0.025) < 1e-9)
    assert on_wall.all() and len(occ) > 100
    assert ((free > 0) & (free < [4.0, 3.0])).all()
    interior = 80 * 60
    assert len(free) > 0.97 * interior


def test_no_return_is_free_up_to_range_max_and_invalid_returns_are_ignored():
    lat = lattice(200, 200)
    pose = np.array([5.0, 5.0, 0.0])
    ranges = np.full(LIDAR.beams, np.inf)
    ranges[:10] = np.nan
    ranges[10:20] = -np.inf
    ranges[20:30] = 9.0  # beyond range_max: invalid
    cells = scan_cells(lat, pose, ranges, LIDAR.angle_min, LIDAR.angle_increment,
                       LIDAR.range_min, LIDAR.range_max)
    assert len(cells.occupied) == 0
    d = np.hypot(*(cells_xy(lat, cells.free) - pose[:2]).T)
    assert d.max() <= LIDAR.range_max + RES
    assert len(cells.free) > 0.9 * math.pi * (LIDAR.range_max / RES) ** 2 * (330 / 360)


def test_returns_on_other_robots_are_not_obstacles():
    lat = lattice()
    pose = np.array([1.0, 1.5, 0.0])
    pose_other = np.array([2.0, 1.5, 0.105])
    ranges = room_scan(pose)
    k = int(round((0.0 - LIDAR.angle_min) / LIDAR.angle_increment))
    ranges[k - 3:k + 4] = 0.9  # the other robot's front
    plain = scan_cells(lat, pose, ranges, LIDAR.angle_min, LIDAR.angle_increment,
                       LIDAR.range_min, LIDAR.range_max)
    robots = scan_cells(lat, pose, ranges, LIDAR.angle_min, LIDAR.angle_increment,
                        LIDAR.range_min, LIDAR.range_max, ignore_discs=pose_other[None])
    near = np.hypot(*(cells_xy(lat, plain.occupied) - pose_other[:2]).T) < 0.2
    assert near.any()
    assert not (np.hypot(*(cells_xy(lat, robots.occupied) - pose_other[:2]).T) < 0.2).any()


@settings(max_examples=25, deadline=None)
@given(x=st.floats(0.3, 7.7), y=st.floats(0.3, 5.7), yaw=st.floats(-math.pi, math.pi),
       seed=st.integers(0, 2 ** 16))
def test_vectorized_model_equals_the_slow_reference(x, y, yaw, seed):
    lat = lattice()
    rng = np.random.default_rng(seed)
    ranges = rng.uniform(0.05, 4.0, LIDAR.beams)
    ranges[rng.random(LIDAR.beams) < 0.2] = np.inf
    ranges[rng.random(LIDAR.beams) < 0.05] = np.nan
    pose = np.array([x, y, yaw])
    args = (lat, pose, ranges, LIDAR.angle_min, LIDAR.angle_increment, LIDAR.range_min,
            LIDAR.range_max)
    fast, slow = scan_cells(*args), reference_scan_cells(*args)
    np.testing.assert_array_equal(fast.free, slow.free)
    np.testing.assert_array_equal(fast.occupied, slow.occupied)


# ---------------------------------------------------------------------------- fusion
def _office_scans(world, poses):
    grid = world.grid
    blocked = grid.occupied_mask()
    out = []
    for p in poses:
        scan = simulate_scan(grid, np.asarray(p, float), LIDAR, np.zeros((0, 2)), np.zeros(0),
                             blocked)
        out.append(scan_cells(grid, np.asarray(p, float), scan.ranges, scan.angle_min,
                              scan.angle_increment, scan.range_min, scan.range_max))
    return out


@pytest.fixture(scope="module")
def office():
    from conftest import WORLDS

    from coverage_ros.core.world import load_world

    return load_world(WORLDS / "office.yaml")


def test_fusing_two_robots_equals_one_robot_seeing_both(office):
    """Robot A's and robot B's scans, exchanged as evidence (in pieces, repeated, out of
    order), give each of them the belief one robot would have after all the scans."""
    config = BeliefConfig(frozen_entropy=0.0)  # no freezing: every scan counts in both
    lat = office.grid
    scans_a = _office_scans(office, [(1.0, 1.0, 0.0), (2.0, 2.0, 1.0), (2.0, 4.0, 0.0)])
    scans_b = _office_scans(office, [(10.0, 6.0, 3.0), (6.0, 4.0, 0.5), (2.0, 4.0, 2.0)])
    a, b, solo = Belief(lat, 0, config), Belief(lat, 1, config), Belief(lat, 9, config)
    for s in scans_a:
        a.add_scan(s)
        solo.add_scan(s)
    for s in scans_b:
        b.add_scan(s)
        solo.add_scan(s)
    # A sends its changes in three messages, one of them twice and the first one last.
    msgs = []
    while (m := a.take_changes(2000)) is not None:
        msgs.append(m)
    assert len(msgs) >= 3
    for m in [*msgs[1:], msgs[1], msgs[0]]:
        b.merge(m)
    while (m := b.take_changes(100000)) is not None:
        a.merge(m)
        a.merge(m)  # a repeat: no double counting
    want = solo.snapshot().log_odds
    np.testing.assert_array_equal(a.snapshot().log_odds, want)
    np.testing.assert_array_equal(b.snapshot().log_odds, want)
    assert a.merge(msgs[0]) == 0  # its own evidence echoed back is ignored
    assert b.merge(msgs[0]) == 0  # already known


def test_a_late_joiner_catches_up_from_refresh_chunks_and_lost_messages_are_repaired(office):
    lat = office.grid
    a = Belief(lat, 0)
    for s in _office_scans(office, [(1.0, 1.0, 0.0), (3.0, 2.0, 1.0)]):
        a.add_scan(s)
    while a.take_changes(10 ** 6) is not None:
        pass  # all of it sent - to nobody: the late joiner missed it
    late = Belief(lat, 5)
    seen = 0
    while seen < 30:
        chunk = a.refresh_chunk(2000)
        assert chunk is not None and len(chunk.cells) <= 2000
        late.merge(chunk)
        seen += 1
    np.testing.assert_array_equal(late.snapshot().log_odds, a.snapshot().log_odds)


def test_frozen_cells_stop_counting_and_entropy_values():
    assert entropy(np.array(0.5)) == pytest.approx(math.log(2))
    assert entropy(np.array(0.0)) == pytest.approx(0.0, abs=1e-9)
    config = BeliefConfig(frozen_entropy=0.3)
    lat = lattice(10, 10)
    b = Belief(lat, 0, config)
    cells = ScanCells(free=np.array([5]), occupied=np.array([7]))
    for _ in range(20):
        b.add_scan(cells)
    e = b.snapshot().entropy.ravel()
    assert e[5] < 0.3 and e[7] < 0.3
    # Frozen after a few scans: at most one scan past the threshold counted.
    lo = config.frozen_log_odds
    assert b.snapshot().log_odds.ravel()[5] >= -(lo + abs(config.l_free)) - 1e-6
    assert b.take_changes(100).misses[0] < 20


def test_occupancy_export_marks_unknown_as_minus_one():
    lat = lattice(4, 4)
    b = Belief(lat, 0)
    b.add_scan(ScanCells(free=np.array([0, 1]), occupied=np.array([2])))
    occ = b.occupancy_percent().ravel()
    assert occ[3] == -1 and 0 < occ[0] < 50 and occ[2] > 50


def test_malformed_evidence_is_clipped_not_fatal():
    lat = lattice(4, 4)
    b = Belief(lat, 0)
    n = b.merge(Evidence(3, np.array([-1, 2, 99, 2]), np.array([1, 1, 1, 4], np.uint16),
                         np.array([0, 0, 0, 0], np.uint16)))
    assert n == 1  # only cell 2 (twice; the larger count wins)
    assert b.snapshot().log_odds.ravel()[2] == pytest.approx(4 * b.config.l_occ)


def test_a_cell_seen_often_enough_is_decided_even_with_mixed_evidence():
    """An obstacle's edge is crossed by some beams and ends others: its log-odds hovers near 0.
    Seen ``edge_after`` times with a quarter or more of returns it is occupied; below a quarter
    the log-odds alone has decided it free - no cell seen that often stays unexplored."""
    config = BeliefConfig()
    lat = lattice(1, 400)
    b = Belief(lat, 0, config)
    cells = np.arange(400)
    seen = cells // 2 + 1  # 1 .. 200 observations
    hits = (cells % 2) * (seen // 3) + (1 - cells % 2) * ((seen - 1) // 4)  # 1/3 or < 1/4
    b.merge(Evidence(1, cells, hits.astype(np.uint16), (seen - hits).astype(np.uint16)))
    p = b.snapshot().probability.ravel()
    e = entropy(p)
    often = seen >= config.edge_after
    edge = often & (hits >= config.edge_share * seen)
    assert edge.any() and (often & ~edge).any()
    np.testing.assert_allclose(p[edge], config.p_max, rtol=1e-6)
    assert (p[often & ~edge] < 0.19).all()
    assert (e[often] < 0.55).all()  # below the explore strategy's tau: explored
    # Before that, the same share of returns leaves the cell undecided (the old dead end).
    assert (e[~often & (cells % 2 == 1) & (hits > 0)] > 0.55).any()
    with pytest.raises(ConfigError, match="edge_after"):
        BeliefConfig(edge_after=0)


def _diamond_scan(pose, centre=(3.0, 2.0), half=0.7):
    """Exact ranges to a square obstacle turned by 45 degrees (its edges are not grid lines)."""
    cx, cy = centre
    corners = np.array([(cx + half, cy), (cx, cy + half), (cx - half, cy), (cx, cy - half)])
    a = pose[2] + LIDAR.angle_min + LIDAR.angle_increment * np.arange(LIDAR.beams)
    d = np.stack([np.cos(a), np.sin(a)], axis=1)
    best = np.full(len(a), np.inf)
    for p0, p1 in zip(corners, np.roll(corners, -1, axis=0), strict=True):
        e = p1 - p0
        w = p0 - np.asarray(pose[:2])
        den = d[:, 0] * (-e[1]) - d[:, 1] * (-e[0])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[0] * (-e[1]) - w[1] * (-e[0])) / den
            s = (d[:, 0] * w[1] - d[:, 1] * w[0]) / den
        ok = (np.abs(den) > 1e-12) & (t > 0) & (s >= 0) & (s <= 1)
        best = np.where(ok & (t < best), t, best)
    return np.where(best <= LIDAR.range_max, best, np.inf)


def test_a_turned_obstacle_seen_from_all_around_is_closed():
    """Scans from a ring of poses around a turned square (edges off the grid lines): its outline
    is closed - its unseen inside cannot be reached from where the robots stand - and almost
    every cell seen is explored."""
    from scipy.ndimage import label

    lat = lattice(80, 120)
    b = Belief(lat, 0)
    for k in range(72):
        t = 2 * math.pi * k / 72
        pose = np.array([3.0 + 1.4 * math.cos(t), 2.0 + 1.4 * math.sin(t), t + 2.0])
        b.add_scan(scan_cells(lat, pose, _diamond_scan(pose), LIDAR.angle_min,
                              LIDAR.angle_increment, LIDAR.range_min, LIDAR.range_max))
    snap = b.snapshot()
    parts, _ = label(snap.probability < 0.65)  # what a planner may cross, unknown included
    inside = tuple(lat.world_to_cell(np.array([[3.0, 2.0]]))[0])
    outside = tuple(lat.world_to_cell(np.array([[4.4, 2.0]]))[0])
    assert not snap.observed[inside] and parts[inside] != parts[outside]
    undecided = snap.observed & (snap.entropy >= 0.55)
    assert undecided.sum() <= 0.01 * snap.observed.sum(), undecided.sum()


def test_footprint_cells_are_the_cells_within_radius_and_half_a_cell():
    lat = lattice(40, 40)
    for xy in ((1.0, 1.0), (1.013, 0.987), (0.03, 0.5), (-0.5, 0.5)):
        got = footprint_cells(lat, np.array(xy), 0.105)
        rows, cols = np.divmod(np.arange(lat.width * lat.height), lat.width)
        centres = lat.cell_centers(np.stack([rows, cols], axis=-1))
        want = np.flatnonzero(np.hypot(*(centres - np.array(xy)).T) <= 0.105 + 0.5 * RES)
        assert np.array_equal(got, want), xy
    assert len(footprint_cells(lat, np.array([1.0, 1.0]), 0.105)) in range(21, 30)


def test_a_body_seen_before_discovery_is_freed_by_the_robots_footprint():
    """A team starts in a cluster and its lidars see each other's bodies for seconds before
    they hear each other's states: the body edges freeze occupied, a ring around each robot's
    start it could never leave (its clearance below the configuration space's). Each robot's
    own footprint is free ground, counted so that it wins in every belief it reaches."""
    lat = lattice()
    a_pose, b_pose = np.array([1.0, 1.5, 0.0]), np.array([1.33, 1.5, math.pi])
    radius = 0.105
    ranges = disc_scan(a_pose, b_pose[:2], radius)
    a, b = Belief(lat, 0), Belief(lat, 1)
    for _ in range(30):  # 3 s at 10 Hz, no neighbour known yet
        a.add_scan(scan_cells(lat, a_pose, ranges, LIDAR.angle_min, LIDAR.angle_increment,
                              LIDAR.range_min, LIDAR.range_max))

    def b_is_free_to_move(belief: Belief) -> bool:
        grid = GridMap(belief.occupancy_percent(), RES)
        # free where believed free or unknown, as an exploring robot plans
        clearance = grid.clearance(unknown_is_free=True)
        col, row = (int(v) for v in np.floor(lat.world_to_grid(b_pose[:2])))
        return bool(clearance[row, col] > radius + 0.5 * RES)

    assert not b_is_free_to_move(a)  # the ring is there, frozen ...
    assert b.merge(a.take_changes(10 ** 6)) > 0 and not b_is_free_to_move(b)
    for _ in range(5):  # ... and B's own scans (blind to its body) cannot clear it
        b.add_scan(scan_cells(lat, b_pose, room_scan(b_pose), LIDAR.angle_min,
                              LIDAR.angle_increment, LIDAR.range_min, LIDAR.range_max))
    assert not b_is_free_to_move(b)
    assert b.add_footprint(footprint_cells(lat, b_pose[:2], radius)) > 0
    assert b_is_free_to_move(b)
    a.merge(b.take_changes(10 ** 6))
    assert b_is_free_to_move(a)
    # Once only: the same footprint again changes nothing (and sends nothing).
    assert b.add_footprint(footprint_cells(lat, b_pose[:2], radius)) == 0
