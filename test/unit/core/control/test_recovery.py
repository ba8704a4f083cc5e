"""Getting unstuck (core/control/recovery.py): a robot held still by its safety filter backs off
and plans again; one held by a neighbour gives way to the right after a longer wait; one paused
or at its goal does not move."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest
from test_navigation import RADIUS, drive, room

from coverage_ros.core.control.controller import ControllerConfig, RobotController
from coverage_ros.core.control.planning import DETOUR_MARGIN, detour, plan_path, segment_free
from coverage_ros.core.control.recovery import (
    ESCAPE_DISTANCE,
    GIVE_WAY_DISTANCE,
    GIVE_WAY_TIME,
    STUCK_TIME,
    away_from,
)
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.world.grid import OCCUPIED, GridMap

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
    assert c.path is None or not c._replan
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


def _closest(bent: np.ndarray, centre: np.ndarray) -> float:
    """[m] the nearest a path ``bent`` comes to ``centre``."""
    pts = np.vstack([a + t * (b - a) for a, b in pairwise(bent)
                     for t in np.linspace(0.0, 1.0, 50)])
    return float(np.hypot(*(pts - centre).T).min())


def _corridor() -> CoverageDomain:
    """A corridor 1.5 m wide along x (free 0.75 .. 2.25 m), 10 m long."""
    occ = np.zeros((60, 200), np.int8)
    occ[:15, :] = occ[45:, :] = OCCUPIED
    return CoverageDomain.from_grid(GridMap(occ, 0.05), RADIUS)


def test_a_detour_bends_the_first_leg_around_the_robot_in_its_way_on_the_free_side():
    d = room(wall=False)
    path = np.array([[1.0, 1.5], [3.0, 1.5]])
    need = np.array([2 * RADIUS + 0.06])
    centre = np.array([1.5, 1.5])
    bent = detour(d, path, centre[None], need)
    assert np.array_equal(bent[0], path[0]) and np.array_equal(bent[-1], path[-1])
    assert (bent[1:-1, 1] < 1.5).all()  # on the right of the way (east: south)
    assert need[0] < _closest(bent, centre) <= need[0] + DETOUR_MARGIN + 1e-9
    assert all(segment_free(d, a, b) for a, b in pairwise(bent))
    # Near the south wall the right side is not free: the left one is taken.
    low = np.array([[1.0, 0.4], [3.0, 0.4]])
    bent = detour(d, low, np.array([[1.5, 0.4]]), need)
    assert (bent[1:-1, 1] > 0.4).all()
    # Nobody in the way (a neighbour beside it, or past the goal): the path as it was.
    for other in ([1.5, 1.9], [3.5, 1.5], [0.5, 1.5]):
        assert detour(d, path, np.array([other]), need) is path
    # In a corridor 0.6 m wide neither side is free: the path as it was.
    occ = np.zeros((60, 80), np.int8)
    occ[:24, :] = occ[36:, :] = OCCUPIED
    corridor = CoverageDomain.from_grid(GridMap(occ, 0.05), RADIUS)
    straight = np.array([[1.0, 1.5], [3.0, 1.5]])
    assert segment_free(corridor, *straight)
    assert detour(corridor, straight, centre[None], need) is straight



def test_a_detour_finds_the_robot_in_its_way_past_a_short_first_leg_and_goes_on_past_it():
    """A path from a robot off the cell centres starts with a leg of a few centimetres to the
    nearest one, here up and to the right; a settled robot a little right of the way along a
    corridor 1.5 m wide stands clear of that leg's line but on the next leg. The path bends
    round it and goes on forward."""
    corridor = _corridor()
    start = np.array([2.015, 1.105])
    path = np.array([start, [2.025, 1.125], [2.125, 1.125], [2.825, 1.125], [8.0, 1.125]])
    neighbour = start + np.array([[0.27, -0.10]])
    need = np.array([2 * RADIUS + 0.06])
    u = (path[1] - path[0]) / np.hypot(*(path[1] - path[0]))
    assert abs(float((neighbour[0] - start) @ np.array([-u[1], u[0]]))) > need[0]
    bent = detour(corridor, path, neighbour, need)
    assert bent is not path
    assert np.array_equal(bent[0], start) and np.array_equal(bent[-1], path[-1])
    assert all(segment_free(corridor, a, b) for a, b in pairwise(bent))
    assert _closest(bent, neighbour[0]) > need[0]
    assert (np.diff(bent[:, 0]) >= -1e-9).all()  # forward all the way: it does not turn back
    # Beyond the reach of a detour, a robot on the way changes nothing (it may move off).
    assert detour(corridor, path, np.array([[5.0, 1.125]]), need) is path


def test_a_detour_round_a_robot_by_the_wall_starts_from_where_the_robot_stands():
    """A relocating robot along a corridor's south wall stands 0.29 m behind and south of a
    settled one, nearer than a bend's radius. The south side is the wall; the bend goes north
    from the robot's own bearing from the neighbour, round behind it, and never comes nearer
    to it than the robot already is - whichever way the few-centimetre snap to the first cell
    centre points (here also back, away from the way)."""
    corridor = _corridor()
    start, neighbour = np.array([2.0, 0.87]), np.array([[2.25, 1.02]])
    need = np.array([2 * RADIUS + 0.06])
    near = float(np.hypot(*(start - neighbour[0])))
    assert near < need[0] + DETOUR_MARGIN
    for snap in ([2.025, 0.875], [1.975, 0.875]):
        path = np.array([start, snap, [3.0, 0.875], [8.0, 0.875]])
        bent = detour(corridor, path, neighbour, need)
        assert bent is not path
        assert np.array_equal(bent[0], start) and np.array_equal(bent[-1], path[-1])
        assert all(segment_free(corridor, a, b) for a, b in pairwise(bent))
        assert _closest(bent, neighbour[0]) >= near - 1e-3
        assert bent[1:-1, 1].max() > neighbour[0, 1] + need[0]  # round the north side


class _GoalAt:
    """A strategy whose goal is always ``goal`` (its cells and states another's)."""

    def __init__(self, strategy, goal: np.ndarray) -> None:
        self._strategy, self._goal = strategy, goal

    def update(self, obs, nbrs):
        import dataclasses

        return dataclasses.replace(self._strategy.update(obs, nbrs), goal=self._goal.copy())

    def __getattr__(self, name):
        return getattr(self._strategy, name)


def test_a_robot_that_gave_way_to_a_standing_neighbour_plans_around_it():
    """Its goal lies straight beyond a neighbour that does not move (a settled robot on a
    relocating one's way): after giving way once it goes round it, never nearer than the
    safety filter allows, instead of planning the same straight line into it again."""
    d = room(wall=False)
    c = RobotController(d, ControllerConfig(robot_id=0))
    goal, other = np.array([3.2, 1.5]), np.array([1.6, 1.5])
    c.strategy = _GoalAt(c.strategy, goal)
    pose, t, closest = np.array([1.0, 1.5, 0.0]), 0.0, np.inf
    while t < 40.0 and float(np.hypot(*(pose[:2] - goal))) > 0.1:
        c.neighbours.receive(1, {"x": other[0], "y": other[1], "vx": 0.0, "vy": 0.0}, now=t)
        c.set_pose(tuple(pose))
        if round(t * 10) % 5 == 0:
            c.update(t)
        v, w = c.command(t, 0.1)
        pose = drive(pose, v, w, 0.1)
        closest = min(closest, float(np.hypot(*(pose[:2] - other))))
        t += 0.1
    assert float(np.hypot(*(pose[:2] - goal))) <= 0.1, (pose, c.describe())
    assert c.recovery.give_ways == 1  # once: the next path went round (planned straight
    # again, it gave way twice and arrived at 30 s instead of 21 s)
    assert closest >= 2 * RADIUS + 0.05


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
