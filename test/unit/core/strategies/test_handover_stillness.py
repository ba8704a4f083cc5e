"""Whether a robot stands still (:mod:`coverage_ros.core.strategies.handover.stillness`)."""

from __future__ import annotations

import numpy as np

from coverage_ros.core.strategies.handover.stillness import STILL_UPDATES, Stillness

TOL = 0.05  # [m] convergence tolerance
SETTLE = 0.1  # [m] the settle step


def _walk(points) -> Stillness:
    s = Stillness()
    for p in points:
        s.note(np.array(p, dtype=np.float64), TOL)
    return s


def test_a_robot_that_does_not_move_stands_after_the_still_updates():
    s = Stillness()
    for _ in range(STILL_UPDATES + 1):
        assert not s.stands()
        s.note(np.array([1.0, 2.0]), TOL)
    assert s.stands() and s.still_for == STILL_UPDATES and s.moved == 0.0


def test_a_robot_dithering_between_two_goals_is_still_but_one_driving_away_is_not():
    # 8 cm back and forth each update (more than the tolerance): going nowhere
    dither = [(1.0 + 0.08 * (k % 2), 2.0) for k in range(STILL_UPDATES + 1)]
    s = _walk(dither)
    assert not s.stands() and s.dithers(SETTLE)
    assert not _walk(dither[:-1]).dithers(SETTLE)  # too few updates to tell
    # 6 cm per update in one direction: 24 cm over the updates, on its way
    drive = [(1.0 + 0.06 * k, 2.0) for k in range(STILL_UPDATES + 1)]
    assert not _walk(drive).stands() and not _walk(drive).dithers(SETTLE)
    # one step out of the disc ends it
    assert not _walk(dither[:-1] + [(1.25, 2.0)]).dithers(SETTLE)


def test_a_restart_forgets_how_the_robot_stood():
    s = _walk([(1.0, 2.0)] * (STILL_UPDATES + 1))
    s.note(np.array([1.0, 2.0]), TOL, restart=True)
    assert not s.stands() and not s.dithers(SETTLE) and len(s.recent) == 1
    for _ in range(STILL_UPDATES):
        s.note(np.array([1.0, 2.0]), TOL)
    assert s.stands() and s.dithers(SETTLE)
