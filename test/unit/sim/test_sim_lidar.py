"""Lidar: analytic ranges, REP 117 conventions, fast caster vs pymunk reference."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import WORLDS, shared_map

from coverage_ros.core.world import LidarSpec, RobotSpec, load_world, parse_world
from coverage_ros.core.world.grid import GridMap
from coverage_ros.sim.lidar import SegmentIndex, beam_angles, ray_circle_ranges
from coverage_ros.sim.static_geometry import grid_boundary_segments
from coverage_ros.sim.world import SimConfig, World


def square_room_ranges(x: float, y: float, angles: np.ndarray, size: float) -> np.ndarray:
    """Distance from (x, y) along each angle to the walls of the room [0, size]^2."""
    c, s = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (size - x) / c, np.where(c < 0, -x / c, np.inf))
        ty = np.where(s > 0, (size - y) / s, np.where(s < 0, -y / s, np.inf))
    return np.minimum(tx, ty)


@pytest.mark.parametrize("pose", [(2.0, 3.0, 0.3), (1.0, 1.0, -2.0), (2.5, 2.5, math.pi)])
def test_ranges_in_a_square_room_match_the_analytic_values(pose):
    world = World(parse_world({"bounds": [0, 0, 5, 5]}), SimConfig())
    robot = world.add_robot(0, pose)
    lidar = robot.spec.lidar
    ranges = world.scan_ranges([0])[0]
    assert ranges.shape == (lidar.beams,) and ranges.dtype == np.float32
    expected = square_room_ranges(pose[0], pose[1], beam_angles(lidar, pose[2]), 5.0)
    far = expected > lidar.range_max
    assert far.any() and (~far).any()
    assert np.all(np.isposinf(ranges[far]))  # REP 117: no return -> +inf
    np.testing.assert_allclose(ranges[~far], expected[~far], atol=1e-5)


def test_ranges_against_a_circle_and_beyond_range():
    spec = parse_world({"bounds": [0, 0, 20, 20],
                        "obstacles": [{"type": "circle", "center": [12, 10], "radius": 0.5}]})
    world = World(spec, SimConfig())
    world.add_robot(0, (10.0, 10.0, 0.0))
    lidar = world.robots[0].spec.lidar
    ranges = world.scan_ranges([0])[0]
    angles = beam_angles(lidar, 0.0)
    expected = ray_circle_ranges(np.array([10.0, 10.0]), angles, np.array([[12.0, 10.0, 0.5]]))
    hit = np.isfinite(expected)
    assert hit.sum() == 2 * int(math.degrees(math.asin(0.5 / 2.0))) + 1  # 29 beams
    np.testing.assert_allclose(ranges[hit], expected[hit], atol=1e-5)
    forward = round(-lidar.angle_min / lidar.angle_increment)  # the beam along the heading
    assert ranges[forward] == pytest.approx(1.5, abs=1e-6)
    assert np.all(np.isposinf(ranges[~hit]))  # walls are 10 m away, beyond range_max


def test_other_robots_are_seen_but_not_the_scanning_robot():
    world = World(parse_world({"bounds": [0, 0, 20, 20]}), SimConfig())
    world.add_robot(0, (10.0, 10.0, 0.0))
    world.add_robot(1, (11.0, 10.0, 0.0), RobotSpec(radius=0.2))
    ranges = world.scan_ranges([0, 1])
    lidar = world.robots[0].spec.lidar
    forward = round(-lidar.angle_min / lidar.angle_increment)
    assert ranges[0, forward] == pytest.approx(0.8, abs=1e-6)  # robot 1's disc
    assert ranges[1, 0] == pytest.approx(1.0 - 0.105, abs=1e-6)  # beam 0 points backwards
    assert np.isfinite(ranges).sum() < 60  # the rest sees nothing, not its own body


def test_too_close_is_minus_inf():
    world = World(parse_world({"bounds": [0, 0, 5, 5]}), SimConfig())
    world.add_robot(0, (0.11, 2.5, 0.0))  # wall 0.11 m behind: closer than range_min 0.12
    ranges = world.scan_ranges([0])[0]
    assert np.isneginf(ranges[0])
    finite = ranges[np.isfinite(ranges)]
    assert finite.min() >= 0.12 and finite.max() <= 3.5


def test_noise_is_seeded_and_stays_within_limits():
    spec = parse_world({"bounds": [0, 0, 5, 5]})
    scans = []
    for _ in range(2):
        world = World(spec, SimConfig(seed=4, scan_noise_std=0.05))
        world.add_robot(0, (1.0, 2.5, 0.0))
        scans.append(world.scan_ranges([0])[0])
    np.testing.assert_array_equal(scans[0], scans[1])
    clean = World(spec, SimConfig())
    clean.add_robot(0, (1.0, 2.5, 0.0))
    exact = clean.scan_ranges([0])[0]
    finite = np.isfinite(exact)
    np.testing.assert_array_equal(np.isfinite(scans[0]), finite)
    err = scans[0][finite] - exact[finite]
    assert 0.03 < err.std() < 0.07
    assert scans[0][finite].min() >= 0.12 and scans[0][finite].max() <= 3.5


def test_partial_field_of_view():
    lidar = LidarSpec(beams=181, fov=math.pi)
    spec = parse_world({"bounds": [0, 0, 5, 5], "lidar": {"beams": 181, "fov": math.pi}})
    world = World(spec, SimConfig())
    world.add_robot(0, (2.5, 2.5, 0.5))
    ranges = world.scan_ranges([0])[0]
    expected = square_room_ranges(2.5, 2.5, beam_angles(lidar, 0.5), 5.0)
    np.testing.assert_allclose(ranges, np.where(expected > 3.5, np.inf, expected), atol=1e-5)


def test_grid_boundary_segments_merge_runs():
    occ = np.zeros((4, 6), dtype=np.int8)
    occ[1:3, 2:5] = 100  # a 2 x 3 block
    segs = grid_boundary_segments(GridMap(occ, 0.5), occ == 100)
    # 4 edges of the block plus 4 edges of the grid border, each merged into one segment.
    assert len(segs) == 8
    lengths = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
    assert sorted(lengths.round(6)) == [1.0, 1.0, 1.5, 1.5, 2.0, 2.0, 3.0, 3.0]


def test_segment_index_returns_all_segments_in_reach():
    rng = np.random.default_rng(1)
    a = rng.uniform(0, 20, (400, 2))
    segs = np.hstack([a, a + rng.normal(0, 1.0, (400, 2))])
    index = SegmentIndex(segs, bucket=1.0)
    for p in rng.uniform(0, 20, (20, 2)):
        near = set(index.near(p[0], p[1], 3.5).tolist())
        d = np.array([_point_segment(p, s) for s in segs])
        assert set(np.flatnonzero(d <= 3.5).tolist()) <= near


def _point_segment(p, s):
    a, b = s[:2], s[2:]
    t = np.clip(np.dot(p - a, b - a) / max(np.dot(b - a, b - a), 1e-300), 0, 1)
    return float(np.hypot(*(a + t * (b - a) - p)))


@pytest.mark.parametrize("world_name", ["office", "field", "depot", "tb3_sandbox"])
def test_fast_caster_matches_pymunk_reference(world_name):
    path = WORLDS / f"{world_name}.yaml"
    if not path.exists():
        path = shared_map(world_name)
    world = World(load_world(path), SimConfig(seed=2))
    ids = world.populate(8)
    for i in ids:
        world.set_command(i, 0.2, 0.3 * (i - 4))
    world.run(2.0)
    fast = world.scan_ranges(ids, caster="fast")
    ref = world.scan_ranges(ids, caster="pymunk")
    same_kind = (np.isposinf(fast) == np.isposinf(ref)) & (np.isneginf(fast) == np.isneginf(ref))
    assert same_kind.mean() > 0.998  # grazing beams at a vertex may differ
    both = np.isfinite(fast) & np.isfinite(ref)
    assert both.sum() > 0.2 * fast.size
    close = np.abs(fast[both] - ref[both]) < 1e-4
    assert close.mean() > 0.998
