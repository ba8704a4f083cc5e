"""The team view's numpy helpers (coverage_ros/viz/team.py): cell labels composed from the
robots' cell grids, trajectory pieces, the schedule of periodic layers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coverage_ros.core.world.grid import GridMap
from coverage_ros.viz.team import Schedule, Trajectory, compose_cell_labels


def test_compose_cell_labels_places_crops_and_later_cells_win():
    grid = GridMap(np.zeros((10, 12)), 0.5, (-1.0, 2.0, 0.0))
    a = GridMap(np.full((4, 3), 100), 0.5, (0.0, 3.0, 0.0))  # rows 2..5, cols 2..4
    b_occ = np.zeros((2, 4))
    b_occ[:, 1:] = 100  # first column not in the cell
    b = GridMap(b_occ, 0.5, (0.5, 4.5, 0.0))  # rows 5..6, cols 3..6, overlaps a at (5, 4)
    off = GridMap(np.full((3, 3), 100), 0.5, (40.0, 40.0, 0.0))  # beyond the map
    edge = GridMap(np.full((3, 3), 100), 0.5, (4.0, 6.0, 0.0))  # rows 8..10, cols 10..12
    labels = compose_cell_labels(grid, [a, b, off, edge])
    expected = np.full((10, 12), -1)
    expected[2:6, 2:5] = 0
    expected[5:7, 4:7] = 1
    expected[8:10, 10:12] = 3
    np.testing.assert_array_equal(labels, expected)
    assert compose_cell_labels(grid, []).max() == -1


def test_compose_cell_labels_resamples_a_rotated_coarser_cell():
    grid = GridMap(np.zeros((40, 40)), 0.1)
    cell = GridMap(np.full((2, 2), 100), 0.5, (2.0, 1.0, math.pi / 4))  # a 1 m square at 45 deg
    labels = compose_cell_labels(grid, [cell])
    X, Y = grid.all_cell_centers()
    u = (X - 2.0) * math.cos(math.pi / 4) + (Y - 1.0) * math.sin(math.pi / 4)
    v = -(X - 2.0) * math.sin(math.pi / 4) + (Y - 1.0) * math.cos(math.pi / 4)
    inside = (u >= 0) & (u < 1.0) & (v >= 0) & (v < 1.0)
    np.testing.assert_array_equal(labels == 0, inside)
    assert inside.sum() == pytest.approx(100, rel=0.1)  # 1 m^2 of 0.01 m^2 cells


def test_trajectory_pieces_join_without_gaps_and_stay_small():
    traj = Trajectory(segment_points=5)
    pts = np.column_stack([np.arange(14) * 0.1, np.zeros(14)])
    for x, y in pts:
        assert traj.add(x, y)
    assert not traj.add(1.3 + 1e-4, 0.0)  # a robot at rest adds nothing
    pieces = traj.take_finished()
    assert [k for k, _ in pieces] == [0, 1, 2] and traj.take_finished() == []
    assert all(len(p) == 5 for _, p in pieces)
    joined = np.vstack([pieces[0][1]] + [p[1:] for _, p in pieces[1:]] + [traj.tail[1:]])
    np.testing.assert_allclose(joined, pts)
    traj.break_path()
    assert [k for k, _ in traj.take_finished()] == [3] and len(traj.tail) == 0


def test_schedule_runs_once_per_period_and_restarts_when_time_goes_back():
    s = Schedule(0.5)
    assert [s.due(t) for t in (0.0, 0.2, 0.5, 0.6, 1.0, 3.0, 3.1)] == \
        [True, False, True, False, True, True, False]
    assert s.due(0.1)  # the simulation was restarted
    always = Schedule(0.0)
    assert all(always.due(t) for t in (1.0, 1.0, 1.1))
