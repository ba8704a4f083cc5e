"""Getting unstuck (core/control/recovery.py): a robot held still by its safety filter backs off
and plans again; one held by a neighbour gives way to the right after a longer wait; one paused
or at its goal does not move."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_navigation import RADIUS, drive, room

from coverage_ros.core.control.controller import ControllerConfig, RobotController
from coverage_ros.core.control.planning import plan_path
from coverage_ros.core.control.recovery import (
    ESCAPE_DISTANCE,
    GIVE_WAY_DISTANCE,
    GIVE_WAY_TIME,
    STUCK_TIME,
    away_from,
)

FACE = np.array([[1.30, y] for y in np.linspace(0.7, 1.3, 25)])  # a box not on the map


def test_away_from_points_the_other_way_and_weighs_the_nearer_more():
    p = np.array([1.0, 1.0])
    assert away_from(p, np.array([[1.2, 1.0]])) == pytest.approx(math.pi)
    assert away_from(p, np.array([[1.0, 0.8]])) == pytest.approx(math.pi / 2)
    # A wall east at 0.15 m and one north at 0.3 m: mostly west, a little south.
    a = away_from(p, np.array([[1.15, 1.0], [1.0, 1.3]]))
    assert -math.pi < a < -0.75 * math.pi
    assert away_from(p, np.array([[3.0, 3.0]])) is None  # nothing near
    assert away_from(p, np.array([[1.2, 1.0], [0.8, 1.0]])) is None  # evenly surrounded


def drive_at_box(c: RobotController, seconds: float, dt: float = 0.1) -> list[tuple]:
    """Commands at 10 Hz from the controller, the robot moving as commanded; (t, pose, v)."""
    out, t = [], 0.0
    pose = np.array(c.pose)
    while t < seconds:
        c.set_pose(tuple(pose))
        v, w = c.command(t, dt)
        out.append((t, pose.copy(), v, c.safety_note))
        pose = drive(pose, v, w, dt)
        t += dt
    return out


def test_a_robot_held_by_an_obstacle_backs_off_and_asks_for_a_new_path():
    c = RobotController(room(wall=False), ControllerConfig(robot_id=0))
    c.set_pose((1.0, 1.0, 0.0))
    c.goal, c.path = np.array([3.0, 1.0]), np.array([[1.0, 1.0], [3.0, 1.0]])
    c.scan_points = FACE
    log = drive_at_box(c, 6.0)
    xs = np.array([p[0] for _, p, _, _ in log])
    assert xs.max() <= 1.30 - RADIUS  # never touched the face
    held = [t for t, _, v, note in log if v == 0.0 and "obstacle in scan" in note]
    escaping = [(t, p) for t, p, _, note in log if note.startswith("escaping")]
    assert held and escaping
    t0 = escaping[0][0]
    assert t0 - held[0] >= STUCK_TIME - 0.15  # held that long first
    x_blocked = escaping[0][1][0]
    assert x_blocked - xs[[t > t0 for t, *_ in log]].min() >= ESCAPE_DISTANCE - 0.01  # backed off
    assert c.recovery.escapes >= 1
    # The escape ended: the path is dropped and the next update plans a new one.
    assert c.path is None or c._replan is False
    res = c.update(7.0)
    assert res is not None and c.path is not None and not c._replan


def test_a_robot_held_by_a_standing_neighbour_waits_then_gives_way_to_the_right():
    c = RobotController(room(wall=False), ControllerConfig(robot_id=0))
    c.set_pose((1.0, 1.0, 0.0))
    c.goal, c.path = np.array([3.0, 1.0]), np.array([[1.0, 1.0], [3.0, 1.0]])
    pose, log = np.array([1.0, 1.0, 0.0]), []
    for k in range(90):  # a neighbour standing 0.25 m ahead, heard every period
        t = 0.1 * k
        c.neighbours.receive(1, {"x": 1.25, "y": 1.0}, now=t)
        c.set_pose(tuple(pose))
        v, w = c.command(t, 0.1)
        log.append((t, pose.copy(), c.safety_note))
        pose = drive(pose, v, w, 0.1)
    waited = [t for t, _, note in log if "robot ahead" in note and "giving way" not in note]
    giving = [(t, p) for t, p, note in log if note.startswith("giving way")]
    assert waited and giving and c.recovery.escapes == 0 and c.recovery.give_ways == 1
    assert giving[0][0] - waited[0] >= GIVE_WAY_TIME - 0.15  # it waited for the neighbour first
    # To the right of its way (east): south, by the give-way distance, never nearer the other.
    end = log[-1][1]
    assert 1.0 - end[1] >= GIVE_WAY_DISTANCE - 0.02
    assert all(np.hypot(p[0] - 1.25, p[1] - 1.0) >= 2 * RADIUS for _, p, _ in log)
    assert c.goal is None and c._replan  # and it plans again from there
    assert any("gave way to a robot ahead 1 time(s)" in line for line in c.describe())


def test_two_robots_head_on_on_one_line_pass_each_other():
    """Each holds the other's way blocked; both give way to their own right and get by."""
    d = room(wall=False)
    robots = [RobotController(d, ControllerConfig(robot_id=i)) for i in range(2)]
    poses = [np.array([0.8, 1.5, 0.0]), np.array([3.2, 1.5, math.pi])]
    goals = [np.array([3.2, 1.5]), np.array([0.8, 1.5])]
    closest, t, dt = np.inf, 0.0, 0.1
    while t < 60.0:
        for i, c in enumerate(robots):
            other = poses[1 - i]
            c.neighbours.receive(1 - i, {"x": other[0], "y": other[1]}, now=t)
            c.set_pose(tuple(poses[i]))
            if c.goal is None or c.path is None:  # (the strategy's next goal: the same one)
                c.goal, c.path = goals[i], plan_path(d, poses[i][:2], goals[i])
                c._replan = False
        commands = [c.command(t, dt) for c in robots]
        poses = [drive(p, v, w, dt) for p, (v, w) in zip(poses, commands, strict=True)]
        closest = min(closest, float(np.hypot(*(poses[0][:2] - poses[1][:2]))))
        t += dt
        if all(np.hypot(*(p[:2] - g)) < 0.1 for p, g in zip(poses, goals, strict=True)):
            break
    assert all(np.hypot(*(p[:2] - g)) < 0.1 for p, g in zip(poses, goals, strict=True)), poses
    assert closest >= 2 * RADIUS
    assert sum(c.recovery.give_ways for c in robots) >= 1


def test_a_paused_robot_does_not_escape():
    c = RobotController(room(wall=False), ControllerConfig(robot_id=0))
    c.scan_points = FACE
    c.set_pose((1.18, 1.0, 0.0))  # right at the face
    c.goal, c.path = np.array([3.0, 1.0]), np.array([[1.0, 1.0], [3.0, 1.0]])
    c.set_paused(True)
    for k in range(60):
        assert c.command(10.0 + 0.1 * k, 0.1) == (0.0, 0.0)
    assert c.recovery.escapes == 0 and c.recovery.give_ways == 0
