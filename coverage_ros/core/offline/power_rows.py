"""Euclidean power Voronoi cells of a grid, row by row.

A power Voronoi cell ``V_k = {q : |q - p_k|^2 - R_k^2 <= |q - p_j|^2 - R_j^2 for all j}`` is an
intersection of half-planes, so it is convex and meets every grid row in one run of cells. On
the row at height ``y`` the condition against robot ``j`` is linear in ``x`` (the ``x^2`` terms
cancel)::

    (a_k - a_j) x <= b_j - b_k,   a_k = -2 x_k,   b_k = x_k^2 + (y - y_k)^2 - R_k^2

which bounds the run from the left or the right (or empties it, when ``x_k = x_j``). A cell
centre exactly on the boundary of two cells goes to the lower index, as the brute-force
labelling (:meth:`coverage_ros.core.offline.lloyd_team.EuclideanTeam.labels`) decides ties.

With running sums along every row of ``w``, ``w x``, ``w y`` and ``w (x^2 + y^2)``
(:class:`RowSums`, built once per grid), a cell's mass, first and second moments are two
look-ups per row: ``O(n^2 H)`` work for ``n`` robots on ``H`` rows instead of the ``O(n H W)``
of labelling every grid cell.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

#: Largest (pairs x rows) block evaluated at once [elements]; bounds the memory.
BLOCK = 1 << 21
#: A cell lighter than this share of the running mass at its runs' ends is summed cell by
#: cell (:meth:`RowSums.moments`): the running sums' rounding (~1e-16 of them) would be
#: ~1e-8 of its own mass and more.
CANCELLATION = 1e-8


@dataclass(frozen=True)
class RowRuns:
    """Every robot's run of grid cells on every row: columns ``start[k, r] <= c < stop[k, r]``
    (``stop <= start``: robot ``k``'s cell misses row ``r``)."""

    start: np.ndarray  # (n, H) int64
    stop: np.ndarray  # (n, H) int64

    def labels(self, width: int) -> np.ndarray:
        """``(H, W) int32``: the robot whose cell holds each grid cell."""
        H = self.start.shape[1]
        first = np.full((H, width + 1), -1, dtype=np.int32)
        k, r = np.nonzero(self.stop > self.start)
        first[r, self.start[k, r]] = k
        first = first[:, :width]
        cols = np.where(first >= 0, np.arange(width), 0)
        np.maximum.accumulate(cols, axis=1, out=cols)
        return np.take_along_axis(first, cols, axis=1)


def row_runs(gx: np.ndarray, gy: np.ndarray, r2: np.ndarray, cx: np.ndarray,
             cy: np.ndarray) -> RowRuns:
    """The runs of the power cells of generators at ``(gx, gy)`` (n,) with squared weights
    ``r2`` over the grid of column centres ``cx`` (W,) and row centres ``cy`` (H,) (all in one
    frame and unit; ``cx`` evenly spaced)."""
    n, H, W = len(gx), len(cy), len(cx)
    start = np.zeros((n, H), dtype=np.int64)
    stop = np.full((n, H), W, dtype=np.int64)
    if n < 2:
        return RowRuns(start, stop)
    pairs = neighbour_pairs(gx, gy, r2) if n >= NEIGHBOURS_FROM else None
    if pairs is None:
        k, j = _all_pairs(n)
    else:
        k, j = pairs
        k, j = k[k < j], j[k < j]
        stop[np.bincount(np.concatenate([k, j]), minlength=n) == 0] = 0  # no neighbour: no cell
    # each pair once, as (left, right) on every row: it bounds left's run on the right and
    # right's run on the left at the same crossing
    swap = gx[k] > gx[j]
    left, right = np.where(swap, j, k), np.where(swap, k, j)
    da = 2.0 * (gx[right] - gx[left])  # a_left - a_right >= 0
    crossing = da > 0
    by_left, by_right = np.argsort(left[crossing], kind="stable"), np.argsort(
        right[crossing], kind="stable")
    lefts, rights = left[crossing][by_left], right[crossing][by_right]
    first_l = np.flatnonzero(np.diff(lefts, prepend=-1))
    first_r = np.flatnonzero(np.diff(rights, prepend=-1))
    step = cx[1] - cx[0] if W > 1 else 1.0
    scale = (1.0 / (da[crossing] * step))[:, None]
    left_wins = (left < right)[crossing][:, None]  # the lower index takes a centre on the line
    b = (gx * gx - r2)[:, None] + (cy[None, :] - gy[:, None]) ** 2  # (n, H)
    li, ri = left[crossing], right[crossing]
    rows = max(1, BLOCK // max(len(li), 1))
    for r0 in range(0, H, rows):
        r1 = min(H, r0 + rows)
        if len(li):
            u = (b[ri, r0:r1] - b[li, r0:r1]) * scale  # the crossing, in columns
            u -= cx[0] / step
            c = np.ceil(u)
            exact = c == u
            if exact.any():  # a centre on the crossing: left's if left takes the tie
                c += exact & left_wins
            # left's run stops and right's starts at the first column past the crossing
            stop[lefts[first_l], r0:r1] = np.clip(
                np.minimum.reduceat(c[by_left], first_l, axis=0), 0, W)
            start[rights[first_r], r0:r1] = np.clip(
                np.maximum.reduceat(c[by_right], first_r, axis=0), 0, W)
        parallel = ~crossing
        if parallel.any():  # robots above each other: the one below the other on the row
            pl, pr = left[parallel], right[parallel]
            db = b[pr, r0:r1] - b[pl, r0:r1]  # > 0: left below right on the row
            tie_left = (pl < pr)[:, None]
            for loser, lose in ((pl, (db < 0) | ((db == 0) & ~tie_left)),
                                (pr, (db > 0) | ((db == 0) & tie_left))):
                gone = np.zeros((n, r1 - r0), dtype=bool)
                np.logical_or.at(gone, loser, lose)
                stop[:, r0:r1][gone] = 0
    return RowRuns(start, stop)


@functools.cache
def _all_pairs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Every pair ``k < j`` of ``n`` robots."""
    k, j = np.triu_indices(n, 1)
    return k, j


#: From this many robots on, a cell is bounded by its neighbours only (the regular
#: triangulation's edges, about 6 per robot) instead of by every other robot.
NEIGHBOURS_FROM = 24


def neighbour_pairs(gx: np.ndarray, gy: np.ndarray,
                    r2: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(k, j)`` sorted by ``k``: the pairs of generators whose power cells share an edge, from
    the lower convex hull of the points lifted to ``(x, y, x^2 + y^2 - R^2)``; None where that
    hull is degenerate (collinear, repeated or coplanar points), and every pair must be used."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.stack([gx, gy], axis=1)
    if len(np.unique(pts, axis=0)) < len(pts):
        return None
    lifted = np.column_stack([pts, gx * gx + gy * gy - r2])
    try:
        hull = ConvexHull(lifted)
    except (QhullError, ValueError):
        return None
    if len(hull.coplanar):
        return None
    tri = hull.simplices[hull.equations[:, 2] < 0]
    if len(tri) == 0:
        return None
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    e = np.unique(np.concatenate([e, e[:, ::-1]]), axis=0)  # sorted by k, then j
    return e[:, 0], e[:, 1]


class RowSums:
    """Running sums along the rows of a grid's cell weights ``w`` (H, W) and their moments, in
    a frame where column ``c`` is centred at ``cx[c]`` and row ``r`` at ``cy[r]``."""

    def __init__(self, w: np.ndarray, cx: np.ndarray, cy: np.ndarray) -> None:
        H, W = w.shape
        self._w, self._cx, self._cy = w, cx, cy
        q = np.zeros((H, W + 1, 4))  # the four sums of one cell side by side: one gather each
        v, x, y = q[:, 1:, :], cx[None, :], cy[:, None]  # (the values of cell_values, in place)
        v[..., 0] = w
        np.multiply(w, x, out=v[..., 1])
        np.multiply(w, y, out=v[..., 2])
        np.multiply(w, x * x + y * y, out=v[..., 3])
        np.cumsum(q, axis=1, out=q)
        self._q = q
        self._rows = np.arange(H)[None, :]

    def cell_values(self) -> np.ndarray:
        """``(4, H, W)``: ``w``, ``w x``, ``w y``, ``w (x^2 + y^2)`` of every grid cell."""
        w, cx, cy = self._w, self._cx[None, :], self._cy[:, None]
        return np.stack([w, w * cx, w * cy, w * (cx * cx + cy * cy)])

    def moments(self, runs: RowRuns) -> np.ndarray:
        """``(n, 4)``: every cell's ``sum w``, ``sum w x``, ``sum w y``, ``sum w (x^2 + y^2)``.

        A cell whose mass is below :data:`CANCELLATION` of the running mass at its runs' ends
        (a cell in a tail of the density beside heavy ones on its rows) is summed cell by
        cell instead: there the differences of running sums are mostly their rounding."""
        stop = np.maximum(runs.stop, runs.start)
        q = self._q
        ends = q[self._rows, stop]
        sums: np.ndarray = (ends - q[self._rows, runs.start]).sum(axis=1)
        for k in np.flatnonzero(sums[:, 0] < CANCELLATION * ends[:, :, 0].sum(axis=1)):
            sums[k] = self._direct(runs.start[k], stop[k])
        return sums

    def _direct(self, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
        """``(4,)`` the sums of :meth:`moments` over the cells ``start[r] <= c < stop[r]`` of
        every row ``r``, added cell by cell."""
        W = self._w.shape[1]
        rows = np.flatnonzero(stop > start)
        counts = stop[rows] - start[rows]
        first = rows * W + start[rows]
        offsets = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        cells = np.repeat(first, counts) + offsets
        r, c = cells // W, cells % W
        w, x, y = self._w[r, c], self._cx[c], self._cy[r]
        return np.array([w.sum(), (w * x).sum(), (w * y).sum(), (w * (x * x + y * y)).sum()])


class RowNearest:
    """The grid cell of a ``mask`` nearest to a point within one cell's runs, row by row: on
    every row the nearest masked column to the left and to the right of the point."""

    def __init__(self, mask: np.ndarray) -> None:
        W = mask.shape[1]
        cols = np.arange(W)
        self._left = np.maximum.accumulate(np.where(mask, cols, -1), axis=1)
        self._right = np.minimum.accumulate(np.where(mask, cols, W)[:, ::-1], axis=1)[:, ::-1]

    def nearest(self, start: np.ndarray, stop: np.ndarray, xy: np.ndarray, cx: np.ndarray,
                cy: np.ndarray) -> tuple[int, int] | None:
        """``(row, col)`` of the masked cell with columns ``start[r] <= col < stop[r]`` whose
        centre is nearest to ``xy`` (ties: the lower row, then the lower column), or None."""
        rows = np.flatnonzero(stop > start)
        if len(rows) == 0:
            return None
        lo, hi = start[rows], stop[rows]
        step = cx[1] - cx[0] if len(cx) > 1 else 1.0
        c0 = np.clip(int(np.floor((xy[0] - cx[0]) / step + 0.5)), lo, hi - 1)
        left, right = self._left[rows, c0], self._right[rows, c0]
        dl = np.where(left >= lo, (cx[np.maximum(left, 0)] - xy[0]) ** 2, np.inf)
        dr = np.where(right < hi, (cx[np.minimum(right, len(cx) - 1)] - xy[0]) ** 2, np.inf)
        take_left = dl <= dr
        d = np.where(take_left, dl, dr) + (cy[rows] - xy[1]) ** 2
        best = int(np.argmin(d))
        if not np.isfinite(d[best]):
            return None
        return int(rows[best]), int(left[best] if take_left[best] else right[best])
