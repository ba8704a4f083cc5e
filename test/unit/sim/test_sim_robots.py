"""Simulator physics: unicycle kinematics with limits, contacts, timeouts, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import WORLDS, shared_map

from coverage_ros.core.world import RobotSpec, load_world, parse_world
from coverage_ros.errors import ConfigError, WorldError
from coverage_ros.sim.world import COLLISION_SLOP, SimConfig, World


def empty_world(size: float = 8.0, **config) -> World:
    spec = parse_world({"bounds": [0, 0, size, size]})
    return World(spec, SimConfig(**config))


def unicycle_reference(pose, commands, spec: RobotSpec, dt: float):
    """Exact unicycle arcs under the same per-step clamping and rate limits, with the
    simulator's one step of actuation delay."""
    x, y, th = pose
    v = w = 0.0
    for cv, cw in [(0.0, 0.0), *commands[:-1]]:
        cv = min(max(cv, -spec.v_max), spec.v_max)
        cw = min(max(cw, -spec.w_max), spec.w_max)
        v += min(max(cv - v, -spec.a_max * dt), spec.a_max * dt)
        w += min(max(cw - w, -spec.alpha_max * dt), spec.alpha_max * dt)
        if abs(w) < 1e-12:
            x, y = x + v * dt * math.cos(th), y + v * dt * math.sin(th)
        else:
            x += v / w * (math.sin(th + w * dt) - math.sin(th))
            y -= v / w * (math.cos(th + w * dt) - math.cos(th))
        th += w * dt
    return x, y, th


@pytest.mark.parametrize("cmd", [(0.2, 0.5), (-0.1, -1.2), (0.22, 0.0), (0.0, 2.0)])
def test_motion_follows_the_unicycle_model_with_rate_limits(cmd):
    world = empty_world(16.0)
    robot = world.add_robot(0, (8.0, 8.0, 0.3))
    dt = world.config.dt
    commands = [cmd] * 100  # 2 s
    for c in commands:
        world.set_command(0, *c)
        world.step()
    ref = unicycle_reference((8.0, 8.0, 0.3), commands, robot.spec, dt)
    x, y, yaw = robot.pose()
    assert math.hypot(x - ref[0], y - ref[1]) < 1e-4
    assert abs(math.remainder(yaw - ref[2], 2 * math.pi)) < 1e-6


def test_commands_are_clamped_and_acceleration_limited():
    world = empty_world(30.0)
    spec = RobotSpec(v_max=0.3, w_max=1.0, a_max=0.5, alpha_max=1.0)
    robot = world.add_robot(0, (5.0, 15.0, 0.0), spec)
    speeds, turns = [], []
    for k in range(150):
        world.set_command(0, 10.0 if k < 100 else -10.0, 5.0)
        world.step()
        vx, vy, w = robot.body_twist()
        speeds.append(math.copysign(math.hypot(vx, vy), vx))
        turns.append(w)
        # No side slip: the velocity points along the heading in the middle of the next step.
        assert abs(vy) <= abs(vx) * math.sin(1.5 * spec.w_max * world.config.dt) + 1e-9
    speeds, turns = np.array(speeds), np.array(turns)
    dt = world.config.dt
    assert np.abs(speeds).max() <= spec.v_max + 1e-6
    assert np.abs(turns).max() <= spec.w_max + 1e-6
    assert np.abs(np.diff(speeds)).max() <= spec.a_max * dt + 1e-6
    assert np.abs(np.diff(turns)).max() <= spec.alpha_max * dt + 1e-6
    assert speeds[99] == pytest.approx(spec.v_max, abs=1e-6)
    assert speeds[-1] < 0  # reversing after the command flipped


def test_non_finite_command_is_rejected():
    world = empty_world()
    world.add_robot(0, (4.0, 4.0, 0.0))
    with pytest.raises(ValueError, match="finite"):
        world.set_command(0, math.nan, 0.0)
    with pytest.raises(ValueError):
        world.set_command(0, 0.1, math.inf)


def test_robot_without_commands_stops_after_the_timeout():
    world = empty_world(16.0)
    robot = world.add_robot(0, (4.0, 8.0, 0.0))
    world.set_command(0, 0.2, 0.0)
    world.run(0.4)
    assert robot.body_twist()[0] == pytest.approx(0.2, abs=1e-6)
    world.run(0.2)  # 0.6 s since the command: timed out, decelerating at a_max
    assert 0.0 <= robot.body_twist()[0] < 0.2
    world.run(0.2)
    assert robot.body_twist()[0] == pytest.approx(0.0, abs=1e-9)
    x = robot.pose()[0]
    world.run(1.0)
    assert robot.pose()[0] == pytest.approx(x, abs=1e-9)


def test_robot_driven_at_a_wall_stops_at_the_wall():
    world = empty_world(4.0)
    robot = world.add_robot(0, (2.0, 2.0, 0.2))
    r, dt = robot.spec.radius, world.config.dt
    # An impact may overlap by at most one step of travel before the contact pushes back.
    impact = robot.spec.v_max * dt + COLLISION_SLOP
    for _ in range(int(15.0 / dt)):
        world.set_command(0, 0.22, 0.0)
        world.step()
        assert robot.pose()[0] <= 4.0 - r + impact
    x, y, _ = robot.pose()
    assert x == pytest.approx(4.0 - r, abs=COLLISION_SLOP + 1e-6)  # resting at the wall
    assert 0.0 + r <= y <= 4.0 - r
    assert robot.wall_collisions == 1 and robot.robot_collisions == 0


def test_head_on_robots_never_overlap_and_both_count_the_collision():
    world = empty_world(8.0)
    a = world.add_robot(0, (3.0, 4.0, 0.0))
    b = world.add_robot(1, (5.0, 4.0, math.pi), RobotSpec(radius=0.15))
    dt = world.config.dt
    contact = a.spec.radius + b.spec.radius
    gaps = []
    for _ in range(int(10.0 / dt)):
        world.set_command(0, 0.22, 0.0)
        world.set_command(1, 0.22, 0.0)
        world.step()
        (xa, ya, _), (xb, yb, _) = a.pose(), b.pose()
        gaps.append(math.hypot(xa - xb, ya - yb) - contact)
    assert min(gaps) >= -(2 * 0.22 * dt + COLLISION_SLOP)  # at most one step of closing travel
    assert gaps[-1] == pytest.approx(0.0, abs=COLLISION_SLOP + 1e-6)  # pushing, not passing
    assert a.robot_collisions == 1 and b.robot_collisions == 1
    assert a.wall_collisions == 0 and b.wall_collisions == 0


def test_heterogeneous_team_uses_each_robots_limits():
    world = empty_world(16.0)
    slow = world.add_robot(0, (2.0, 4.0, 0.0), RobotSpec(v_max=0.1))
    fast = world.add_robot(1, (2.0, 10.0, 0.0), RobotSpec(radius=0.2, v_max=0.5, a_max=1.0))
    commands = [(1.0, 0.0)] * int(4.0 / world.config.dt)
    for c in commands:
        world.set_command(0, *c)
        world.set_command(1, *c)
        world.step()
    for robot, start in ((slow, (2.0, 4.0, 0.0)), (fast, (2.0, 10.0, 0.0))):
        ref = unicycle_reference(start, commands, robot.spec, world.config.dt)
        assert robot.pose() == pytest.approx(ref, abs=1e-6)
    assert fast.pose()[0] - 2.0 > 4.5 * (slow.pose()[0] - 2.0)
    assert fast.path_length == pytest.approx(fast.pose()[0] - 2.0, abs=1e-6)


def test_odometry_starts_at_the_spawn_pose_and_is_exact_without_noise():
    world = empty_world(16.0)
    robot = world.add_robot(0, (5.0, 6.0, 1.0))
    for k in range(200):
        world.set_command(0, 0.2, 0.8 if k < 120 else -0.5)
        world.step()
    x, y, yaw = robot.pose()
    c, s = math.cos(1.0), math.sin(1.0)
    ex, ey = c * (x - 5.0) + s * (y - 6.0), -s * (x - 5.0) + c * (y - 6.0)
    assert robot.odom.x == pytest.approx(ex, abs=1e-9)
    assert robot.odom.y == pytest.approx(ey, abs=1e-9)
    assert math.remainder(robot.odom.yaw - (yaw - 1.0), 2 * math.pi) == pytest.approx(0, abs=1e-9)


def _trajectory(seed: int, noise: bool) -> tuple[np.ndarray, np.ndarray, list]:
    spec = load_world(WORLDS / "empty.yaml")
    config = SimConfig(seed=seed, odom_noise_trans=0.02 if noise else 0.0,
                       odom_noise_rot=0.02 if noise else 0.0,
                       scan_noise_std=0.01 if noise else None)
    world = World(spec, config)
    ids = world.populate(6)
    scans = []
    for k in range(150):
        for i in ids:
            world.set_command(i, 0.2, math.sin(0.05 * k + i))
        scans.extend(world.step())
    true = np.array([world.robots[i].pose() for i in ids])
    odom = np.array([(world.robots[i].odom.x, world.robots[i].odom.y) for i in ids])
    return true, odom, scans


def test_same_seed_gives_the_same_trajectories_and_scans():
    t1, o1, s1 = _trajectory(7, noise=True)
    t2, o2, s2 = _trajectory(7, noise=True)
    np.testing.assert_array_equal(t1, t2)
    np.testing.assert_array_equal(o1, o2)
    assert len(s1) == len(s2) > 0
    for a, b in zip(s1, s2, strict=True):
        assert a.robot_id == b.robot_id and a.stamp == b.stamp
        np.testing.assert_array_equal(a.ranges, b.ranges)
    t3, _, _ = _trajectory(8, noise=True)
    assert not np.allclose(t1, t3)  # another seed: another start cluster
    # Noise streams are separate: odometry noise does not move the true trajectory.
    t4, o4, _ = _trajectory(7, noise=False)
    np.testing.assert_array_equal(t1, t4)
    assert not np.allclose(o1, o4)


def test_world_start_poses_then_free_placement():
    spec = parse_world({"bounds": [0, 0, 6, 6], "robots": [[1, 1, 0], [2, 1, 0.5]]})
    world = World(spec, SimConfig(seed=3))
    assert world.populate(4) == [0, 1, 2, 3]
    assert world.robots[1].pose()[:2] == pytest.approx((2.0, 1.0))
    pts = np.array([world.robots[i].pose()[:2] for i in range(4)])
    d = np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1))
    assert d[np.triu_indices(4, 1)].min() >= 2 * world.robots[0].spec.radius


def test_add_and_remove_robots_at_run_time():
    world = empty_world()
    world.add_robot(0, (4.0, 4.0, 0.0))
    world.run(0.5)
    with pytest.raises(WorldError, match="already in use"):
        world.add_robot(0, (2.0, 2.0, 0.0))
    with pytest.raises(WorldError, match="overlaps"):
        world.add_robot(1, (4.1, 4.0, 0.0))
    with pytest.raises(WorldError, match="inside an obstacle or wall"):
        world.add_robot(1, (0.05, 4.0, 0.0))
    with pytest.raises(WorldError, match="outside the map"):
        world.add_robot(1, (40.0, 4.0, 0.0))
    robot = world.add_robot(world.free_id())
    assert robot.id == 1 and robot.spawn_time == pytest.approx(0.5)
    world.run(0.5)
    world.remove_robot(0)
    assert list(world.robots) == [1] and len(world.space.bodies) == 2  # robot 1's two bodies
    with pytest.raises(WorldError, match="no such robot"):
        world.remove_robot(0)
    world.run(0.5)


def test_config_validation_names_the_field():
    with pytest.raises(ConfigError, match="physics_rate_hz"):
        SimConfig(physics_rate_hz=0.0)
    with pytest.raises(ConfigError, match="cmd_timeout"):
        SimConfig(cmd_timeout=-1.0)
    with pytest.raises(ConfigError, match="seed"):
        SimConfig(seed=-3)


def test_warehouse_map_becomes_few_shapes():
    # How long it takes is a benchmark figure (scripts/bench_world: setup_seconds).
    path = shared_map("warehouse")
    world = World(load_world(path), SimConfig())
    cells = world.spec.base_map.occupancy.size
    assert world.geometry.shape_count < 0.01 * cells
    world.populate(8)
    world.run(1.0)
