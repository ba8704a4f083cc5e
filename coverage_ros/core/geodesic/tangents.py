"""Tangents at a robot of the geodesics to the cells of its Voronoi cell (Bhattacharya et al. 2014,
Eq. 8).

The control law needs, for every point q of the robot's cell, the unit tangent at the robot p
of the shortest path p -> q. The paper's pseudo-code uses the first edge of the graph path,
which on an 8-connected grid can only point in 8 directions, and since many octile paths tie,
which of them is found is arbitrary. Two better estimates, both read off the shortest-path tree
with vectorized *binary lifting* (ancestor tables of depth 2^k):

* Euclidean metric: the geodesic is straight until it first wraps an obstacle corner, so its
  tangent points at the last point of the path still in line of sight of p. That is q itself
  when q is visible (giving exactly ``q - p``), else the deepest visible ancestor of q. Line of
  sight comes from a polar depth map of the blocked cells around p (a virtual lidar).
* Other metrics (sphere, torus, entropy-weighted exploration): geodesics curve, so the tangent
  is the chord to the ancestor at a small look-ahead distance along the path.
"""

from __future__ import annotations

import math

import numpy as np

#: [cells] radius of the disc that covers a blocked unit cell (half its diagonal).
CELL_HALF_DIAGONAL = math.sqrt(0.5)
#: [cells] side of the square tiles whose line of sight :func:`sight_tiles` decides whole.
SIGHT_TILE = 16
#: Runs of depth bins are written bin by bin while they hold fewer bins than the span times
#: its power-of-two levels over this, as blocks beyond (measured at 2048-8192 bins: the two
#: ways take about as long there).
BLOCKS_FROM = 5
#: sight tiles spanning more than 2**10 depth bins (close to the origin) are not decided whole
_WIDEST_LEVEL = 10


def ancestor_table(parent: np.ndarray) -> list[np.ndarray]:
    """Binary-lifting tables ``up[k][v]`` = the 2^k-th ancestor of ``v``.

    ``parent`` is ``(n + 1,)``: indices into the same array, with the root at index ``n``
    pointing to itself.
    """
    up = [parent]
    n = len(parent)
    for _ in range(max(1, int(math.ceil(math.log2(max(n, 2)))))):
        nxt = up[-1][up[-1]]
        if np.array_equal(nxt, up[-1]):
            break
        up.append(nxt)
    return up


def first_ancestor_where(up: list[np.ndarray], start: np.ndarray, flag: np.ndarray) -> np.ndarray:
    """For each ``start[i]``, the nearest ancestor-or-self ``a`` with ``flag[a]`` True, assuming
    ``flag`` is True on a prefix of every root path (the root's flag must be True)."""
    cur = start.copy()
    done = flag[cur]
    todo = ~done
    if not todo.any():
        return cur
    c = cur[todo]
    for table in reversed(up):
        cand = table[c]
        move = ~flag[cand]
        c = np.where(move, cand, c)
    cur[todo] = up[0][c]
    return cur


def polar_depth(origin: np.ndarray, blocked_xy: np.ndarray, bins: int) -> np.ndarray:
    """``(bins,)`` [cells]: distance from ``origin`` to the nearest blocked cell along each
    direction, modelling each blocked cell (centre ``blocked_xy (M, 2)``, grid coordinates) as a
    disc of radius :data:`CELL_HALF_DIAGONAL` (conservative: a cell never looks see-through).

    A disc sets the least of its nearest distance over the run of bins it spans: written bin
    by bin when the runs are short in all (:func:`_least_bin_by_bin`), else as power-of-two
    blocks (:func:`_least_by_blocks`); the same minima either way."""
    depth = np.full(bins, np.inf)
    if len(blocked_xy) == 0:
        return depth
    d = blocked_xy - origin
    dist = np.hypot(d[:, 0], d[:, 1])
    theta = np.arctan2(d[:, 1], d[:, 0])
    half = np.arcsin(np.minimum(1.0, CELL_HALF_DIAGONAL / np.maximum(dist, 1e-9)))
    near = np.maximum(dist - CELL_HALF_DIAGONAL, 0.0)
    step = 2.0 * math.pi / bins
    lo = np.floor((theta - half + math.pi) / step).astype(np.int64)
    hi = np.floor((theta + half + math.pi) / step).astype(np.int64)
    base = int(lo.min())  # (runs reach a quarter turn past either end: unwrapped here)
    lo -= base
    hi -= base
    span = int(hi.max()) + 1
    counts = hi - lo + 1
    # (blocks cost about two passes over the span per level; bins one write each)
    if int(counts.sum()) * BLOCKS_FROM < span * int(counts.max()).bit_length():
        least = _least_bin_by_bin(lo, counts, near, span)
    else:
        least = _least_by_blocks(lo, hi, near, span)
    np.minimum.at(depth, (np.arange(span) + base) % bins, least)
    return depth


def _least_bin_by_bin(lo: np.ndarray, counts: np.ndarray, values: np.ndarray,
                      span: int) -> np.ndarray:
    """``(span,)``: the least of ``values[i]`` over the runs of bins ``lo[i] ..
    lo[i] + counts[i] - 1`` that hold each bin (inf where none), every bin of every run
    written."""
    least = np.full(span, np.inf)
    rep = np.repeat(np.arange(len(lo)), counts)
    offs = np.arange(rep.size) - np.repeat(np.cumsum(counts) - counts, counts)
    np.minimum.at(least, lo[rep] + offs, values[rep])
    return least


def _least_by_blocks(lo: np.ndarray, hi: np.ndarray, values: np.ndarray,
                     span: int) -> np.ndarray:
    """:func:`_least_bin_by_bin` of the runs ``lo[i] .. hi[i]``, each written as the two
    power-of-two blocks that cover it (a sparse table read backwards) and the blocks pushed
    down level by level to single bins: work linear in the bins and runs, however long."""
    level = np.floor(np.log2(hi - lo + 1)).astype(np.int64)
    levels = int(level.max()) + 1
    table = np.full((levels, span), np.inf)  # [k, i]: least over bins i .. i + 2**k - 1
    at = level * span
    np.minimum.at(table.ravel(), np.concatenate([at + lo, at + hi - (1 << level) + 1]),
                  np.concatenate([values, values]))
    for k in range(levels - 1, 0, -1):
        h = 1 << (k - 1)
        np.minimum(table[k - 1], table[k], out=table[k - 1])
        np.minimum(table[k - 1][h:], table[k][:-h], out=table[k - 1][h:])
    least: np.ndarray = table[0]
    return least


def visible_from(origin: np.ndarray, points: np.ndarray, depth: np.ndarray,
                 tiles: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """``(N,) bool``: points (grid coordinates) closer to ``origin`` than the depth map's
    obstacle along their direction.

    ``tiles``, optional, is ``(states, point_tiles)``: :func:`sight_tiles` of this origin and
    depth map, and :func:`tile_index` of the points. Points in a tile decided whole take its
    answer; only the others are tested one by one. The answer is the same either way."""
    if tiles is not None:
        states, point_tiles = tiles
        s = np.where(point_tiles >= 0, states[np.maximum(point_tiles, 0)], -1)
        out: np.ndarray = s == 1
        mixed = np.flatnonzero(s < 0)
        if len(mixed):
            out[mixed] = visible_from(origin, points[mixed], depth)
        return out
    d = points - origin
    dist = np.hypot(d[:, 0], d[:, 1])
    bins = len(depth)
    idx = (np.floor((np.arctan2(d[:, 1], d[:, 0]) + math.pi) / (2.0 * math.pi / bins))
           .astype(np.int64) % bins)
    visible: np.ndarray = dist <= depth[idx]
    return visible


def tile_index(points: np.ndarray, shape: tuple[int, int], tile: int = SIGHT_TILE) -> np.ndarray:
    """``(N,)`` the flat index (row-major) of the :func:`sight_tiles` tile holding each point
    (grid coordinates) of a grid of ``shape`` cells; -1 for a point outside the grid."""
    H, W = shape
    nx = -(-W // tile)
    col = np.floor(points[:, 0] / tile)
    row = np.floor(points[:, 1] / tile)
    inside = (points[:, 0] >= 0) & (points[:, 0] < W) & (points[:, 1] >= 0) & (points[:, 1] < H)
    return np.where(inside, row * nx + col, -1).astype(np.int64)


def sight_tiles(origin: np.ndarray, depth: np.ndarray, shape: tuple[int, int],
                tile: int = SIGHT_TILE, ids: np.ndarray | None = None) -> np.ndarray:
    """``(ny * nx,) int8`` over the square tiles of ``tile`` x ``tile`` cells of a grid of
    ``shape`` cells (row-major; tile ``(i, j)`` spans x in ``[j tile, (j + 1) tile]``, y in
    ``[i tile, (i + 1) tile]``): 1 where :func:`visible_from` ``origin`` with ``depth`` is true
    for every point of the tile, 0 where it is false for every one, -1 where it may vary (or
    the tile holds the origin).

    A tile away from the origin spans an angle under pi: its points' directions fall in the
    bins between its corners' (one more bin each side for rounding), and their distances
    between the tile's nearest and farthest point. It is seen whole when its farthest point is
    nearer than every depth of those bins, and hidden whole when its nearest point is beyond
    all of them. Range minima and maxima come from sparse tables over the depth map repeated
    three times (so that a range crossing the angle -pi reads on unbroken).

    ``ids``: only these tiles (flat row-major indices), in their order (the same answer for
    each)."""
    H, W = shape
    nx = -(-W // tile)
    if ids is None:
        ids = np.arange(-(-H // tile) * nx)
    if len(ids) == 0:
        return np.zeros(0, dtype=np.int8)
    x0 = (ids % nx) * float(tile) - origin[0]
    y0 = (ids // nx) * float(tile) - origin[1]
    x1, y1 = x0 + tile, y0 + tile
    holds = (x0 <= 0) & (x1 >= 0) & (y0 <= 0) & (y1 >= 0)
    near = np.hypot(np.maximum(np.maximum(x0, -x1), 0.0), np.maximum(np.maximum(y0, -y1), 0.0))
    far = np.hypot(np.maximum(np.abs(x0), np.abs(x1)), np.maximum(np.abs(y0), np.abs(y1)))
    mid = np.arctan2((y0 + y1) / 2.0, (x0 + x1) / 2.0)
    corners = np.arctan2(np.stack([y0, y0, y1, y1]), np.stack([x0, x1, x0, x1]))
    off = (corners - mid + math.pi) % (2.0 * math.pi) - math.pi  # |off| < 3 pi / 4
    bins = len(depth)
    step = 2.0 * math.pi / bins
    lo = np.floor((mid + off.min(axis=0) + math.pi) / step).astype(np.int64) - 1 + bins
    hi = np.floor((mid + off.max(axis=0) + math.pi) / step).astype(np.int64) + 1 + bins
    lo = np.clip(lo, 0, 3 * bins - 1)
    hi = np.clip(np.maximum(hi, lo), 0, 3 * bins - 1)
    level = np.floor(np.log2(hi - lo + 1)).astype(np.int64)
    wide = holds | (level > _WIDEST_LEVEL)  # (tiles next to the origin: tested point by point)
    level = np.minimum(level, _WIDEST_LEVEL)
    base = int(lo.min())
    least, most = _range_tables(np.tile(depth, 3)[base:int(hi.max()) + 1], int(level.max()) + 1)
    lo, right = lo - base, np.maximum(hi - base - (1 << level) + 1, 0)
    lowest = np.minimum(least[level, lo], least[level, right])
    highest = np.maximum(most[level, lo], most[level, right])
    states = np.full(len(ids), -1, dtype=np.int8)
    states[(far * (1.0 + 1e-12) + 1e-9 <= lowest) & ~wide] = 1
    states[(near - 1e-9 > highest) & ~wide] = 0
    return states


def _range_tables(values: np.ndarray, levels: int) -> tuple[np.ndarray, np.ndarray]:
    """Sparse tables ``(levels, len(values))``: entry ``[k, i]`` is the minimum (maximum) of
    ``values[i : i + 2**k]`` (as far as the array goes)."""
    least = np.empty((levels, len(values)))
    most = np.empty((levels, len(values)))
    least[0] = most[0] = values
    for k in range(1, levels):
        h = 1 << (k - 1)
        least[k] = least[k - 1]
        most[k] = most[k - 1]
        np.minimum(least[k - 1][:-h], least[k - 1][h:], out=least[k][:-h])
        np.maximum(most[k - 1][:-h], most[k - 1][h:], out=most[k][:-h])
    return least, most


def depth_bins(radius_cells: float) -> int:
    """Angular bins for a depth map that must resolve single cells out to ``radius_cells``."""
    return int(np.clip(2 ** math.ceil(math.log2(max(2.0 * math.pi * radius_cells * 2.0, 64.0))),
                       256, 8192))
