"""The whole domain's multi-source search (equal weights, ``visibility`` sources) without
searching where the answer is already known.

In ``visibility`` mode every source is joined to each free cell in its line of sight at the
straight-line distance, and no path is shorter than the straight line (Euclidean metric). So a
cell ``q`` in line of sight of the generator ``k`` that is nearest to it in straight-line
distance (tie bias included) is settled before any search: its distance is ``|q - p_k|``, its
label ``k``, its shortest-path parent the source itself - every other generator's path to it is
at least its own straight line, which is no shorter. Only the remaining cells (hidden from that
generator behind an obstacle) need a Dijkstra, and only over themselves and the settled cells
bordering them: a shortest path into the hidden region can be taken to leave the settled region
for good at its last settled cell. On an open map nothing is left to search.

The arrays returned are those of the full search (``dist``, ``pred``, ``label`` over the local
ids of the whole-domain search graph: sink 0, nodes, then one source per generator), so
:func:`coverage_ros.core.geodesic.cell._shared_search` uses them as it would its own.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain, tie_bias
from coverage_ros.core.geodesic.local_search import LocalGraph


def visible_first_search(domain: CoverageDomain, local: LocalGraph,
                         snaps: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(dist, pred, label)`` of the min-only multi-source search from the generators whose
    :meth:`CoverageDomain.snap` results are ``snaps`` (in source order) on the whole-domain
    search graph ``local`` (module docstring)."""
    n = local.n
    first = n + 1
    k_gens = len(snaps)
    res = domain.resolution
    free = local.seedable
    centers = local.centers
    # Straight-line seed cost of every free cell from every generator; the snap edges (the
    # generator's own and adjacent cells, or the nearest free cell when it stands on a blocked
    # one) are seeds too, at their own cost.
    grids = np.array([s[2] for s in snaps])
    biases = np.array([tie_bias(g) for g in grids])
    H, W = domain.shape  # the whole-domain graph's local ids are node ids + 1 (row-major)
    cx, cy = np.arange(W) + 0.5, np.arange(H) + 0.5
    best = np.full((H, W), np.inf)
    winner = np.full((H, W), -1, dtype=np.int64)
    for k in range(k_gens):  # squared distances separate into a row and a column term
        d = np.sqrt((cy[:, None] - grids[k, 1]) ** 2 + (cx[None, :] - grids[k, 0]) ** 2)
        d *= res
        d += biases[k]
        np.putmask(winner, d < best, k)
        np.minimum(best, d, out=best)
    best, winner = best.ravel(), winner.ravel()
    best[~free] = np.inf
    winner[~free] = -1
    snap_best: list[tuple[np.ndarray, np.ndarray]] = []
    for k, (nodes, costs, _) in enumerate(snaps):
        lid = local.local_of(nodes)
        keep = lid > 0
        snap_best.append((lid[keep] - 1, costs[keep]))
        for i, c in zip(lid[keep] - 1, costs[keep], strict=True):
            if c < best[i]:
                best[i], winner[i] = c, k
    # Settled: in line of sight of the winner (snap seeds of the winner count as seen).
    settled = np.zeros(n, dtype=bool)
    # One depth map per generator over the whole domain (the reach of its farthest corner)
    # serves both line-of-sight passes.
    depths: dict = {}
    for k in range(k_gens):
        mine = np.flatnonzero(winner == k)
        if len(mine) == 0:
            continue
        gx, gy = grids[k]
        reach = math.hypot(max(gx, W - gx), max(gy, H - gy))
        settled[mine] = domain.visible_mask(grids[k], centers[mine], reach, depths)
        own_snap = snap_best[k][0]
        settled[own_snap[winner[own_snap] == k]] = True
    dist = np.full(first + k_gens, np.inf)
    pred = np.full(first + k_gens, -9999, dtype=np.int32)
    label = np.full(first + k_gens, -1, dtype=np.int64)
    ids = np.flatnonzero(settled)
    dist[ids + 1] = best[ids]
    pred[ids + 1] = first + winner[ids]
    label[ids + 1] = winner[ids]
    hidden = np.flatnonzero(free & ~settled)
    if len(hidden):
        _search_hidden(domain, local, hidden, settled, dist, pred, label, grids, biases,
                       snap_best, depths)
    return dist, pred, label


def _search_hidden(domain: CoverageDomain, local: LocalGraph, hidden: np.ndarray,
                   settled: np.ndarray, dist: np.ndarray, pred: np.ndarray, label: np.ndarray,
                   grids: np.ndarray, biases: np.ndarray,
                   snap_best: list[tuple[np.ndarray, np.ndarray]], depths: dict) -> None:
    """Dijkstra over the hidden cells from their settled neighbours and from every generator's
    own seeds among them (in line of sight, or snap edges); fills the arrays in place."""
    n = local.n
    first = n + 1
    res = domain.resolution
    k_gens = len(grids)
    nb, edge = local.nb[hidden], local.edge[hidden]  # local ids (1..n; 0 = sink)
    border = np.unique(nb[edge & settled[np.maximum(nb - 1, 0)] & (nb > 0)]) - 1
    sub = np.concatenate([hidden, border])  # sub index -> node index
    pos = np.full(n + 1, -1, dtype=np.int64)  # (index n: the tables' "no edge" sentinel)
    pos[sub] = np.arange(len(sub))
    m = len(sub)
    # Hidden rows: their graph edges within the sub-graph; border rows: edges into hidden
    # cells. A visibility domain's graph is the grid's own (no chart edges): its edge table.
    nb_table, cost_table = domain.graph.edge_table
    counts, cols, vals = [], [], []
    for start in (hidden, border):
        to = nb_table[start]  # (s, K) node ids, n where there is no edge
        inside = pos[to] >= 0
        if start is border:
            inside &= ~np.append(settled, True)[to]
        counts.append(inside.sum(axis=1))  # row-major selection: rows stay in order
        cols.append(pos[to[inside]])
        vals.append(cost_table[start][inside])
    # One virtual source per generator: to its border cells at their settled distance, and to
    # the hidden cells it snaps to or sees (at its snap / straight-line cost).
    to_border, snap_cost = [], []
    for k in range(k_gens):
        mine = border[label[border + 1] == k]
        to_border.append((pos[mine], dist[mine + 1]))
        snap_nodes, snap_costs = snap_best[k]
        hid = (pos[snap_nodes] >= 0) & ~settled[snap_nodes]  # hidden: pos < len(hidden)
        cost = np.full(len(hidden), np.inf)
        np.minimum.at(cost, pos[snap_nodes[hid]], snap_costs[hid])
        snap_cost.append(cost)
    size = m + k_gens
    sources = np.arange(m, size)
    # First without the straight lines into hidden cells: the distances found are lengths of
    # real paths, so a straight-line seed that is no shorter cannot change any distance (nor,
    # being strictly longer, any label or parent): only the others need a line-of-sight test,
    # which is most of this search's cost (a team bunched in a corner of depot leaves half of
    # the map hidden from its nearest robot; a few hundred cells then get a shorter line).
    d, p, src = dijkstra(_graph(counts, cols, vals, to_border, snap_cost, size), directed=True,
                         indices=sources, min_only=True, return_predecessors=True)
    upper = d[:len(hidden)]
    hc = local.centers[hidden]
    shorter = False
    for k in range(k_gens):
        e = np.hypot(hc[:, 0] - grids[k, 0], hc[:, 1] - grids[k, 1]) * res + biases[k]
        better = np.flatnonzero(e <= upper + 1e-9)
        if len(better):
            reach = float(np.max(e[better] - biases[k])) / res
            seen = better[domain.visible_mask(grids[k], hc[better], reach, depths)]
            np.minimum.at(snap_cost[k], seen, e[seen])
            shorter = shorter or bool(len(seen))
    if shorter:  # (a line no shorter than the path found changes nothing: the first stands)
        d, p, src = dijkstra(_graph(counts, cols, vals, to_border, snap_cost, size),
                             directed=True, indices=sources, min_only=True,
                             return_predecessors=True)
    h = np.arange(len(hidden))
    reached = np.isfinite(d[h])
    lid = hidden[h[reached]] + 1
    dist[lid] = d[h[reached]]
    label[lid] = src[h[reached]] - m
    parent = p[h[reached]]
    from_source = parent >= m
    mapped = np.where(from_source, first + (parent - m), sub[np.minimum(parent, m - 1)] + 1)
    pred[lid] = mapped


def _graph(counts: list[np.ndarray], cols: list[np.ndarray], vals: list[np.ndarray],
           to_border: list[tuple[np.ndarray, np.ndarray]], seeds: list[np.ndarray],
           size: int) -> csr_matrix:
    """The sub-graph's rows in order (``counts`` edges each, their ``cols`` and ``vals``),
    then per generator k a source row to its border cells (``to_border[k]``: sub indices and
    costs) and to every hidden cell with a finite ``seeds[k]`` cost; built as CSR directly
    (no edge appears twice, so there is nothing to sum or sort)."""
    counts, cols, vals = list(counts), list(cols), list(vals)
    for (b_cols, b_vals), cost in zip(to_border, seeds, strict=True):
        to = np.flatnonzero(np.isfinite(cost))
        counts.append(np.array([len(b_cols) + len(to)]))
        cols += [b_cols, to]
        vals += [b_vals, cost[to]]
    indptr = np.zeros(size + 1, dtype=np.int32)
    np.cumsum(np.concatenate(counts), out=indptr[1:])
    return csr_matrix((np.maximum(np.concatenate(vals), 1e-12),  # 0 would be no edge
                       np.concatenate(cols).astype(np.int32), indptr), shape=(size, size))
