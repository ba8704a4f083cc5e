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
    disc of radius :data:`CELL_HALF_DIAGONAL` (conservative: a cell never looks see-through)."""
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
    counts = hi - lo + 1
    rep = np.repeat(np.arange(len(lo)), counts)
    offs = np.arange(rep.size) - np.repeat(np.cumsum(counts) - counts, counts)
    np.minimum.at(depth, (lo[rep] + offs) % bins, near[rep])
    return depth


def visible_from(origin: np.ndarray, points: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """``(N,) bool``: points (grid coordinates) closer to ``origin`` than the depth map's
    obstacle along their direction."""
    d = points - origin
    dist = np.hypot(d[:, 0], d[:, 1])
    bins = len(depth)
    idx = (np.floor((np.arctan2(d[:, 1], d[:, 0]) + math.pi) / (2.0 * math.pi / bins))
           .astype(np.int64) % bins)
    return dist <= depth[idx]


def depth_bins(radius_cells: float) -> int:
    """Angular bins for a depth map that must resolve single cells out to ``radius_cells``."""
    return int(np.clip(2 ** math.ceil(math.log2(max(2.0 * math.pi * radius_cells * 2.0, 64.0))),
                       256, 8192))
