"""Getting unstuck (core/control/recovery.py): a robot held still by its safety filter backs off
and plans again; one held by a neighbour, paused or at its goal does not."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_navigation import RADIUS, drive, room

from coverage_ros.core.control.controller import ControllerConfig, RobotController
from coverage_ros.core.control.recovery import ESCAPE_DISTANCE, STUCK_TIME, away_from

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


def test_a_robot_held_by_a_neighbour_or_paused_does_not_escape():
    c = RobotController(room(wall=False), ControllerConfig(robot_id=0))
    c.set_pose((1.0, 1.0, 0.0))
    c.goal, c.path = np.array([3.0, 1.0]), np.array([[1.0, 1.0], [3.0, 1.0]])
    for k in range(60):  # a neighbour standing 0.25 m ahead, heard every period
        c.neighbours.receive(1, {"x": 1.25, "y": 1.0}, now=0.1 * k)
        c.command(0.1 * k, 0.1)
    assert "robot ahead" in c.safety_note and c.recovery.escapes == 0
    c.neighbours = type(c.neighbours)(c.domain.geometry.extent(), 2.0)
    c.scan_points = FACE
    c.set_pose((1.18, 1.0, 0.0))  # right at the face
    c.set_paused(True)
    for k in range(60):
        assert c.command(10.0 + 0.1 * k, 0.1) == (0.0, 0.0)
    assert c.recovery.escapes == 0
