"""Making way for a relocating neighbour (coverage_ros.core.control.make_way): a robot whose goal
is a doorway on a relocating neighbour's way steps off that way, stays off it while the
neighbour comes through, takes its goal again once the neighbour has passed, and keeps its
decision where it blocks no one or has no room to step aside."""

from __future__ import annotations

import numpy as np
import pytest

from coverage_ros.core.control.controller import ControllerConfig, RobotController
from coverage_ros.core.control.make_way import (
    AHEAD,
    MARGIN,
    ahead,
    distance_to_path,
    make_way,
)
from coverage_ros.core.control.planning import plan_path
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies import Decision, Neighbour
from coverage_ros.core.strategies.base import SharedState, mode_code
from coverage_ros.core.world.grid import OCCUPIED, GridMap

RADIUS = 0.105  # [m]
KEEP = 0.3  # [m] centre distance the safety filter keeps (two radii and a margin)


def _rooms(door: float = 0.9) -> CoverageDomain:
    """A 6 x 6 m square at 5 cm cut by a wall at y = 3 m with a door ``door`` wide at x = 3 m."""
    occ = np.zeros((120, 120), dtype=np.int8)
    occ[59:61, :] = OCCUPIED
    half = int(round(door / 2 / 0.05))
    occ[59:61, 60 - half:60 + half] = 0
    return CoverageDomain.from_grid(GridMap(occ, 0.05, (0.0, 0.0, 0.0)), RADIUS)


def _corridor() -> CoverageDomain:
    """A 6 m corridor 0.5 m wide (y 2.75-3.25 m): no room beside a robot in it."""
    occ = np.full((120, 120), OCCUPIED, dtype=np.int8)
    occ[55:65, :] = 0
    return CoverageDomain.from_grid(GridMap(occ, 0.05, (0.0, 0.0, 0.0)), RADIUS)


def _decision(goal) -> Decision:
    g = np.asarray(goal, dtype=np.float64)
    return Decision(goal=g, velocity=None, cell=np.zeros(0, dtype=np.int64),
                    shared=SharedState(g), converged=True, cost=0.0, mass=1.0, mode="lloyd")


def _relocating(position, to, relocating: float = 1.0) -> Neighbour:
    extra = {"relocating": relocating, "to_x": float(to[0]), "to_y": float(to[1]),
             "radius": RADIUS}
    return Neighbour(7, SharedState(np.asarray(position, dtype=np.float64), extra=extra))


def _keep(_n: Neighbour) -> float:
    return KEEP


def test_ahead_and_distance_to_a_path():
    path = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0]])
    assert ahead(path, 5.0) == pytest.approx(np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 2.0]]))
    assert ahead(path, 9.0) is path
    d = distance_to_path(path, np.array([[1.0, 1.0], [4.0, 3.0], [-3.0, -4.0], [3.0, 5.0]]))
    assert d == pytest.approx([1.0, 1.0, 5.0, 1.0])


def test_a_robot_in_a_doorway_steps_off_the_way_until_the_neighbour_has_passed():
    domain = _rooms()
    goal = np.array([3.05, 3.25])  # just inside the upper room, in front of the door
    to = np.array([3.0, 1.0])  # the neighbour's point in the lower room
    here = goal.copy()
    n = _relocating([2.2, 4.2], to)
    d = make_way(domain, _decision(goal), np.array([*here, 0.0]), [n], _keep)
    assert d.mode == "make_way" and not d.converged
    spot = d.goal
    assert np.hypot(*(spot - here)) <= 1.5
    way = ahead(plan_path(domain, n.position, to), AHEAD)
    assert distance_to_path(way, spot[None])[0] >= KEEP + MARGIN
    assert domain.is_free_point(spot)
    # standing there, it stays there (its own goal is still on the way) ...
    again = make_way(domain, _decision(goal), np.array([*spot, 0.0]), [n], _keep)
    assert again.mode == "make_way"
    assert np.hypot(*(again.goal - spot)) < 0.1
    # ... until the neighbour is through the door and its way ahead no longer passes the goal
    past = _relocating([3.0, 2.2], to)
    back = make_way(domain, _decision(goal), np.array([*spot, 0.0]), [past], _keep)
    assert back.mode == "lloyd" and back.goal == pytest.approx(goal)


def test_nothing_changes_for_robots_off_the_way_or_neighbours_that_do_not_relocate():
    domain = _rooms()
    goal = np.array([5.0, 5.0])  # far from the door and the neighbour's way
    n = _relocating([2.2, 4.2], [3.0, 1.0])
    d = make_way(domain, _decision(goal), np.array([*goal, 0.0]), [n], _keep)
    assert d.mode == "lloyd" and d.goal == pytest.approx(goal)
    door = np.array([3.05, 3.25])
    settled = _relocating([2.2, 4.2], [3.0, 1.0], relocating=0.0)
    d = make_way(domain, _decision(door), np.array([*door, 0.0]), [settled], _keep)
    assert d.mode == "lloyd"
    far = _relocating([0.5, 5.8], [3.0, 1.0])  # relocating, but farther than NEAR
    d = make_way(domain, _decision(door), np.array([*door, 0.0]), [far], _keep)
    assert d.mode == "lloyd"


def test_a_relocating_robot_does_not_make_way():
    domain = _rooms()
    door = np.array([3.05, 3.25])
    d = _decision(door)
    d = Decision(d.goal, None, d.cell, d.shared, False, 0.0, 1.0, mode="relocate")
    out = make_way(domain, d, np.array([*door, 0.0]), [_relocating([2.2, 4.2], [3, 1])], _keep)
    assert out is d


def test_in_a_corridor_too_narrow_to_step_aside_the_decision_stands():
    domain = _corridor()
    goal = np.array([3.0, 3.0])
    n = _relocating([1.5, 3.0], [5.5, 3.0])
    d = make_way(domain, _decision(goal), np.array([*goal, 0.0]), [n], _keep)
    assert d.mode == "lloyd" and d.goal == pytest.approx(goal)


def test_the_controller_makes_way_for_a_relocating_neighbour_it_hears():
    """Through :class:`RobotController`: a robot standing in the doorway hears a neighbour
    relocating through it and heads off its way; once that neighbour says it has arrived, the
    robot's own strategy decides again."""
    domain = _rooms()
    c = RobotController(domain, ControllerConfig(robot_id=0))
    c.set_pose((3.0, 3.0, 0.0))
    heard = {"x": 2.2, "y": 4.2, "weight": 0.0, "mass": 1.0, "relocating": 1.0, "to_x": 3.0,
             "to_y": 1.0, "radius": RADIUS}
    assert c.neighbours.receive(7, heard, now=1.0) == ""
    result = c.update(1.0)
    assert result is not None and result.decision.mode == "make_way"
    assert result.state["mode"] == mode_code("make_way")
    way = plan_path(domain, np.array([2.2, 4.2]), np.array([3.0, 1.0]))
    assert distance_to_path(way, result.decision.goal[None])[0] >= KEEP
    assert c.neighbours.receive(7, {**heard, "x": 3.0, "y": 1.0, "relocating": 0.0},
                                now=2.0) == ""
    assert c.update(2.0).decision.mode != "make_way"


def test_a_neighbours_way_is_planned_once_and_followed_from_where_it_stands(monkeypatch):
    import coverage_ros.core.control.make_way as mw

    planned = []

    def counting(domain, start, goal, *args):
        planned.append(tuple(start))
        return plan_path(domain, start, goal, *args)

    monkeypatch.setattr(mw, "plan_path", counting)
    domain, known = _rooms(), mw.Ways()
    to = np.array([3.0, 1.0])
    first = known.of(domain, _relocating([2.2, 4.2], to), to)
    on = first[0] + 0.5 * (first[1] - first[0]) + np.array([0.05, 0.0])  # drove on, a bit off
    later = known.of(domain, _relocating(on, to), to)
    assert len(planned) == 1
    assert later[0] == pytest.approx(on) and later[-1] == pytest.approx(to)
    assert distance_to_path(first, later[1:]) == pytest.approx(0.0, abs=1e-9)
    known.of(domain, _relocating([5.5, 5.5], to), to)  # strayed: planned again
    known.of(domain, _relocating([5.5, 5.5], [1.0, 1.0]), np.array([1.0, 1.0]))  # new point
    assert len(planned) == 3
