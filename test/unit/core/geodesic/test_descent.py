"""From the Lloyd control to a reachable goal (core/geodesic/descent.py): a blocked straight
step must not leave a robot standing where its cell's centroid lies beyond an obstacle."""

from __future__ import annotations

import numpy as np

from coverage_ros.core.geodesic.descent import descent_walk, reachable_goal
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.world.grid import OCCUPIED, GridMap

RES = 0.05


def jamb_domain() -> tuple[CoverageDomain, int]:
    """A room (rows >= 21) over a corridor (rows <= 14), joined by a door in columns 0-5; the
    robot's vertex (row 20, column 6) is a notch at the door jamb: the wall is right of it and
    below it, the way on into the corridor starts with a step to the left (a robot there held
    the corridor and the rooms beyond in its cell, its goal 5 cm away)."""
    occ = np.zeros((40, 60), np.int8)
    occ[15:20, 6:] = OCCUPIED
    occ[20, 7:] = OCCUPIED
    domain = CoverageDomain.from_grid(GridMap(occ, RES), 0.0)
    return domain, 20 * 60 + 6


def test_a_robot_at_a_door_jamb_steps_round_it_toward_its_centroid():
    domain, base = jamb_domain()
    own = domain.node_centers(np.array([base]))[0]
    step = np.array([30.0, -60.0])  # [cells] down and right: into the corridor, beyond the wall
    direction = step / np.hypot(*step)
    # Every step along the gradient is blocked here: the paper's rule repeated goes nowhere.
    walk = descent_walk(domain, base, step, 20.0)
    assert np.hypot(*(walk - own)) < 1.0
    goal = reachable_goal(domain, base, own, step, step)
    assert (goal - own) @ direction >= 10.0, goal  # well on the way, not stuck at the jamb
    assert goal[1] < 15.0  # in the corridor, past the wall
    row, col = int(goal[1]), int(goal[0])
    assert domain.free[row, col]


def test_an_open_step_is_kept_as_it_was():
    domain, base = jamb_domain()
    own = domain.node_centers(np.array([base]))[0]
    step = np.array([-3.0, 12.0])  # up into the room: nothing in the way
    assert np.allclose(reachable_goal(domain, base, own, step, step), own + step)
