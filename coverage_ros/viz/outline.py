"""The outline of a cell given as a mask on a grid: the edges between cells in the mask and
cells outside it (or the grid's border), as map-frame segments. Pure numpy; RViz line lists and
pictures draw these."""

from __future__ import annotations

import numpy as np

from coverage_ros.core.world.grid import GridMap


def outline_segments(mask: np.ndarray, grid: GridMap) -> np.ndarray:
    """``(K, 2, 2)`` [m] segments ``[[x0, y0], [x1, y1]]`` of the boundary of ``mask (H, W)``
    (row 0 at the grid's origin, as in :class:`GridMap`); collinear unit edges are merged into
    runs so that a straight side is one segment."""
    m = np.asarray(mask, dtype=bool)
    padded = np.pad(m, 1)
    segs: list[np.ndarray] = []
    # Horizontal edges: between row r-1 and row r (corner rows 0..H), where the mask changes.
    horiz = padded[1:, 1:-1] != padded[:-1, 1:-1]  # (H + 1, W): edge below row r
    segs.append(_runs(horiz, horizontal=True))
    vert = padded[1:-1, 1:] != padded[1:-1, :-1]  # (H, W + 1): edge left of column c
    segs.append(_runs(vert.T, horizontal=False))
    corners = np.concatenate(segs).reshape(-1, 2)  # (col, row) corner coordinates
    if len(corners) == 0:
        return np.zeros((0, 2, 2))
    world = grid.grid_to_world(corners)
    return world.reshape(-1, 2, 2)


def _runs(edges: np.ndarray, horizontal: bool) -> np.ndarray:
    """Corner coordinates ``(K, 2, 2)`` (col, row) of the maximal runs of True along each row
    of ``edges`` (rows: corner lines; columns: unit steps)."""
    e = np.pad(edges.astype(np.int8), ((0, 0), (1, 1)))
    d = np.diff(e, axis=1)
    line, start = np.nonzero(d == 1)
    line_end, end = np.nonzero(d == -1)
    assert np.array_equal(line, line_end)
    if horizontal:  # line = corner row, start/end = columns
        a = np.stack([start, line], axis=-1)
        b = np.stack([end, line], axis=-1)
    else:  # line = corner column, start/end = rows
        a = np.stack([line, start], axis=-1)
        b = np.stack([line, end], axis=-1)
    return np.stack([a, b], axis=1).astype(np.float64).reshape(-1, 2, 2)
