"""Every grid cell's nearest generator in straight-line distance, tie bias included (what
:func:`coverage_ros.core.geodesic.visible_first.visible_first_search` settles first), without
measuring every cell's distance to every generator.

The nearest generator without the bias is the Euclidean Voronoi cell holding the cell centre,
found row by row (:func:`coverage_ros.core.offline.power_rows.row_runs`: ``O(n^2 H)`` or, from
``NEIGHBOURS_FROM`` generators on, ``O(n H)`` work instead of ``O(n H W)``). The bias (below
:data:`~coverage_ros.core.geodesic.domain.TIE_BIAS`) and rounding can only change that answer
where two generators are nearly as far: on row ``y`` the squared distances of generators ``k``
and ``j`` differ by ``alpha x + beta``, linear in ``x``, so the cells where ``|d_j - d_k|``
could be below :data:`NEAR_TIE_CELLS` form one short interval per pair and row. Only those
cells are measured, exactly as the brute-force loop does (``sqrt(dy^2 + dx^2) * res + bias``,
ties to the lower index); every other cell keeps its Voronoi cell's generator, at its exact
distance.
"""

from __future__ import annotations

import numpy as np

from coverage_ros.core.geodesic.domain import TIE_BIAS
from coverage_ros.core.offline.power_rows import RowRuns, _all_pairs, row_runs

__all__ = ["straight_winner"]

#: [chart units] Two generators' biased straight-line distances can swap order only where
#: their unbiased ones differ by less than the largest bias difference (TIE_BIAS) plus
#: rounding (far below 1e-12 relative); twice that is taken.
NEAR_TIE = 2.0 * TIE_BIAS


def straight_winner(grids: np.ndarray, biases: np.ndarray, shape: tuple[int, int],
                    resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """``(best, winner)``: ``(H * W,)`` row-major, for every cell centre the least of
    ``|q - g_k| * resolution + biases[k]`` over the generators at grid points ``grids (n, 2)``
    [cells] and the first ``k`` that attains it (module docstring)."""
    H, W = shape
    n = len(grids)
    gx = np.ascontiguousarray(grids[:, 0], dtype=np.float64)
    gy = np.ascontiguousarray(grids[:, 1], dtype=np.float64)
    cx, cy = np.arange(W) + 0.5, np.arange(H) + 0.5
    biases = np.asarray(biases, dtype=np.float64)
    runs = row_runs(gx, gy, np.zeros(n), cx, cy)
    dy2 = (cy[None, :] - gy[:, None]) ** 2  # (n, H), as the brute-force loop's row term
    k, r = np.nonzero(runs.stop > runs.start)
    start = runs.start[k, r]
    order = np.lexsort((start, r))  # row by row, left to right
    k, r, start = k[order], r[order], start[order]
    length = runs.stop[k, r] - start
    new_row = np.ones(len(r), dtype=bool)
    new_row[1:] = r[1:] != r[:-1]
    last = np.append(new_row[1:], True)
    if (len(np.unique(r)) == H and (start[new_row] == 0).all() and (start[1:][~new_row[1:]]
            == (start + length)[:-1][~new_row[1:]]).all() and (start + length)[last].max() == W
            and ((start + length)[last] == W).all()):
        # the runs tile every row: the winner's terms repeated along its run (no gathers)
        winner = np.repeat(k, length)
        grid = np.repeat(dy2[k, r], length).reshape(H, W)
        grid += (cx[None, :] - np.repeat(gx[k], length).reshape(H, W)) ** 2
        np.sqrt(grid, out=grid)
        grid *= resolution
        grid += np.repeat(biases[k], length).reshape(H, W)
        best: np.ndarray = grid.ravel()
    else:  # (rounding left a gap or an overlap: every generator's distance in those cells)
        winner = runs.labels(W).ravel().astype(np.int64)
        best = np.full(H * W, np.inf)
        mine = np.flatnonzero(winner >= 0)
        best[mine] = _measure(mine // W, mine % W, winner[mine], gx, gy, biases, resolution)
    if n > 1:
        changed = _settle_near_ties(winner, runs, gx, gy, biases, shape, resolution)
        best[changed] = _measure(changed // W, changed % W, winner[changed], gx, gy, biases,
                                 resolution)
    return best, winner


def _measure(rows: np.ndarray, cols: np.ndarray, k: np.ndarray, gx: np.ndarray,
             gy: np.ndarray, biases: np.ndarray, resolution: float) -> np.ndarray:
    """``sqrt(dy^2 + dx^2) * resolution + bias`` of cells ``(rows, cols)`` from generators
    ``k`` (as the brute-force loop computes it, bit for bit)."""
    d: np.ndarray = (rows + 0.5 - gy[k]) ** 2
    d += (cols + 0.5 - gx[k]) ** 2
    np.sqrt(d, out=d)
    d *= resolution
    d += biases[k]
    return d


def _settle_near_ties(winner: np.ndarray, runs: RowRuns, gx: np.ndarray, gy: np.ndarray,
                      biases: np.ndarray, shape: tuple[int, int], resolution: float
                      ) -> np.ndarray:
    """Measure the cells where two generators are nearly as far (module docstring) and give
    each the brute-force loop's answer (``winner`` changed in place); returns the cells
    measured. Cells no Voronoi run covers (there should be none) are measured against every
    generator."""
    H, W = shape
    n = len(gx)
    k, j = _all_pairs(n)  # (not only neighbours: four or more generators on one circle tie
    # at its centre, where the triangulation joins only some of them)
    # A cell of k's run on the bisector of k and j is |p_k - p_j| / 2 from p_k at least: pairs
    # farther apart than twice both cells' reach cannot tie in any cell of either.
    has = runs.stop > runs.start
    far_x = np.maximum(np.abs(runs.start + 0.5 - gx[:, None]),
                       np.abs(runs.stop - 0.5 - gx[:, None]))  # (n, H) the run's far end
    dy = np.arange(H)[None, :] + 0.5 - gy[:, None]
    cell_reach = np.sqrt(np.where(has, far_x ** 2 + dy ** 2, 0.0).max(axis=1)) + 1.0
    near = np.hypot(gx[k] - gx[j], gy[k] - gy[j]) <= 2.0 * np.maximum(cell_reach[k],
                                                                        cell_reach[j])
    k, j = k[near], j[near]
    # |d_j - d_k| = |d_j^2 - d_k^2| / (d_j + d_k): a bound of the sum turns the distance
    # tolerance into one of the squared distances' difference (cells^2)
    reach = np.hypot(np.maximum(np.abs(gx), np.abs(W - gx)),
                     np.maximum(np.abs(gy), np.abs(H - gy)))  # to the farthest corner
    tol = (NEAR_TIE / resolution + 1e-9) * 2.0 * float(reach.max())
    y = np.arange(H) + 0.5
    alpha = 2.0 * (gx[k] - gx[j])  # d_j^2 - d_k^2 = alpha x + beta(y)
    beta = (gx[j] ** 2 - gx[k] ** 2)[:, None] + (y[None, :] - gy[j][:, None]) ** 2 \
        - (y[None, :] - gy[k][:, None]) ** 2  # (pairs, H)
    flat = alpha == 0.0  # (pairs above each other: the whole row or none of it)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(flat, 1.0, alpha)[:, None]
        x0, x1 = (-beta - tol) / a, (-beta + tol) / a
    lo = np.where(flat[:, None], np.where(np.abs(beta) <= tol, -np.inf, np.inf),
                  np.minimum(x0, x1))
    hi = np.where(flat[:, None], np.inf, np.maximum(x0, x1))
    # columns whose centre c + 0.5 lies in [lo, hi]
    c0 = np.clip(np.ceil(lo - 0.5), 0, W).astype(np.int64)
    c1 = np.clip(np.floor(hi - 0.5) + 1, 0, W).astype(np.int64)
    p, r = np.nonzero(c1 > c0)
    counts = (c1 - c0)[p, r]
    ends = np.cumsum(counts)
    offsets = np.arange(ends[-1] if len(ends) else 0) - np.repeat(ends - counts, counts)
    cells = np.repeat(r * W + c0[p, r], counts) + offsets
    pair = np.repeat(p, counts)
    w = winner[cells]
    mine = (w == k[pair]) | (w == j[pair])  # (another winner: nearer than both, or a pair
    cells, pair = cells[mine], pair[mine]  # of its own marks the cell)
    uncovered = np.flatnonzero(winner < 0)
    cand_cells = np.concatenate([cells, cells, np.repeat(uncovered, n)])
    cand = np.concatenate([k[pair], j[pair], np.tile(np.arange(n), len(uncovered))])
    if len(cand) == 0:
        return cand
    d = _measure(cand_cells // W, cand_cells % W, cand, gx, gy, biases, resolution)
    order = np.lexsort((cand, d, cand_cells))  # per cell: the least distance, then index
    first = np.ones(len(order), dtype=bool)
    first[1:] = cand_cells[order][1:] != cand_cells[order][:-1]
    pick = order[first]
    winner[cand_cells[pick]] = cand[pick]
    changed: np.ndarray = cand_cells[pick]
    return changed
