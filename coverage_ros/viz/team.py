"""The team as a viewer sees it: small numpy state behind the rerun bridge (no ROS, no rerun).

* :func:`compose_cell_labels` merges the robots' cropped cell grids into one label grid on the
  map's lattice (what :meth:`CoverageRecorder.log_cells` draws).
* :class:`~coverage_ros.core.control.pose_history.PoseHistory` (from the core) keeps a robot's
  recent poses so a scan is placed with the pose at the scan's stamp, not the latest one.
* :class:`Trajectory` grows a driven path in bounded segments: re-logging a whole path every
  time would make a recording grow with the square of its length.
* :class:`Schedule` says when a periodic job is due on the (simulation) time of the messages.

Points are ``(N, 2) float64`` arrays of ``(x, y)`` [m] in the ``map`` frame; poses are
``(x, y, yaw)`` tuples [m, m, rad] in the ``map`` frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from coverage_ros.core.control.pose_history import TIME_JUMP_BACK
from coverage_ros.core.world.grid import GridMap

#: [percent] a cell-grid value at or above this is part of the robot's cell (cells publish 100).
CELL_THRESHOLD = 50
#: [m] trajectory points closer than this to the previous one are skipped (a robot at rest).
TRAJECTORY_MIN_STEP = 0.01


def compose_cell_labels(grid: GridMap, cells: Sequence[GridMap],
                        threshold: int = CELL_THRESHOLD) -> np.ndarray:
    """``(H, W) int64`` label grid on ``grid``: ``k`` where ``cells[k]`` claims the map cell,
    ``-1`` where no cell does.

    Each ``cells[k]`` is one robot's cell, cropped to its bounding box, in the ``map`` frame
    (values >= ``threshold`` belong to the cell). A map cell takes the value of the cell grid
    at its centre, so cell grids on another lattice, resolution or rotation are resampled.
    Where cells overlap (one robot's message is newer than its neighbour's), the later entry
    of ``cells`` wins.

    >>> from coverage_ros.core.world.grid import GridMap
    >>> m = GridMap(np.zeros((3, 4)), 1.0)
    >>> c = GridMap(np.full((1, 2), 100), 1.0, (1.0, 1.0, 0.0))
    >>> compose_cell_labels(m, [c]).tolist()
    [[-1, -1, -1, -1], [-1, 0, 0, -1], [-1, -1, -1, -1]]
    """
    labels = np.full(grid.shape, -1, dtype=np.int64)
    for k, cell in enumerate(cells):
        block = _overlap(grid, cell)
        if block is None:
            continue
        r0, r1, c0, c1 = block
        rows, cols = np.mgrid[r0:r1, c0:c1]
        centres = grid.cell_centers(np.stack([rows.ravel(), cols.ravel()], axis=-1))
        where = cell.world_to_cell(centres)
        inside = cell.contains_cell(where)
        mine = np.zeros(len(centres), dtype=bool)
        mine[inside] = cell.occupancy[where[inside, 0], where[inside, 1]] >= threshold
        sub = labels[r0:r1, c0:c1]
        sub[mine.reshape(sub.shape)] = k
    return labels


def _overlap(grid: GridMap, cell: GridMap) -> tuple[int, int, int, int] | None:
    """``(r0, r1, c0, c1)``: the block of ``grid`` cells under ``cell``'s extent, or None."""
    w, h = cell.width, cell.height
    corners = cell.grid_to_world(np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]]))
    g = grid.world_to_grid(corners)
    c0, r0 = np.floor(g.min(axis=0)).astype(int)
    c1, r1 = np.ceil(g.max(axis=0)).astype(int)
    r0, c0 = max(int(r0), 0), max(int(c0), 0)
    r1, c1 = min(int(r1), grid.height), min(int(c1), grid.width)
    if r0 >= r1 or c0 >= c1:
        return None
    return r0, r1, c0, c1


class Trajectory:
    """A driven path split into segments of at most ``segment_points`` points.

    Only the open *tail* changes; a full segment is handed out once by :meth:`take_finished`
    and never changes again, so logging costs O(points * segment_points) in total instead of
    O(points^2). Consecutive segments share their joining point, so the path has no gaps;
    :meth:`break_path` starts a new piece without joining it (a robot that vanished and came
    back, or a time jump).
    """

    def __init__(self, segment_points: int = 100) -> None:
        if segment_points < 2:
            raise ValueError(f"segment_points must be >= 2 (got {segment_points})")
        self.segment_points = segment_points
        self._tail: list[tuple[float, float]] = []
        self._finished: list[tuple[int, np.ndarray]] = []
        self._count = 0  # segments finished so far (names of the finished parts)

    @property
    def tail(self) -> np.ndarray:
        return np.array(self._tail, dtype=np.float64).reshape(-1, 2)

    def add(self, x: float, y: float) -> bool:
        """Append a point; False when it is within TRAJECTORY_MIN_STEP of the last one."""
        if self._tail and math.hypot(x - self._tail[-1][0],
                                     y - self._tail[-1][1]) < TRAJECTORY_MIN_STEP:
            return False
        self._tail.append((float(x), float(y)))
        if len(self._tail) >= self.segment_points:
            self._finish()
            self._tail = [self._finished[-1][1][-1].tolist()]
        return True

    def break_path(self) -> None:
        if len(self._tail) > 1:
            self._finish()
        self._tail = []

    def _finish(self) -> None:
        self._finished.append((self._count, self.tail))
        self._count += 1

    def take_finished(self) -> list[tuple[int, np.ndarray]]:
        """Segments finished since the last call, as ``(index, (M, 2) points)``."""
        done, self._finished = self._finished, []
        return done


class Schedule:
    """Due every ``period`` seconds of message time (``period`` 0: always due)."""

    def __init__(self, period: float) -> None:
        self.period = period
        self._next = -math.inf

    def due(self, t: float) -> bool:
        """True (and the next run is scheduled) when ``t`` reached the next run time."""
        if t < self._next - self.period - TIME_JUMP_BACK:
            self._next = -math.inf  # time went back: a new run
        if t + 1e-9 < self._next:
            return False
        self._next += self.period
        if self._next <= t:  # first run, or a long gap: restart the phase here
            self._next = t + self.period
        return True
