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
:func:`coverage_ros.core.geodesic.shared_search.shared_search` uses them as it would its own.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain, Snap
from coverage_ros.core.geodesic.local_search import LocalGraph
from coverage_ros.core.geodesic.sight import DepthMaps
from coverage_ros.core.geodesic.straight_winner import straight_winner
from coverage_ros.core.geodesic.tangents import SIGHT_TILE


def visible_first_search(domain: CoverageDomain, local: LocalGraph,
                         snaps: list[Snap]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
    biases = np.array([domain.bias(g) for g in grids])
    H, W = domain.shape  # the whole-domain graph's local ids are node ids + 1 (row-major)
    best, winner = straight_winner(grids, biases, (H, W), res)
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
    first_free = first + k_gens
    dist = np.full(first_free, np.inf)
    pred = np.full(first_free, -9999, dtype=np.int32)
    label = np.full(first_free, -1, dtype=np.int64)
    rect = domain.free_rectangle
    if rect is not None and ((grids[:, 0] >= rect[0]) & (grids[:, 0] <= rect[2])
                             & (grids[:, 1] >= rect[1]) & (grids[:, 1] <= rect[3])).all():
        # (free cells filling a rectangle with every generator in it: each sees them all, so
        # every free cell is settled by its winner and nothing is hidden)
        dist[1:first] = best
        label[1:first] = winner
        pred[1:first] = np.where(winner >= 0, first + winner, -9999)
        return dist, pred, label
    # Settled: in line of sight of the winner (snap seeds of the winner count as seen). Cells
    # in a tile seen (hidden) whole from their winner are settled (not) by the tile's answer,
    # the others one by one (the same answers), each generator's from one depth map of every
    # occluder (kept in the domain; the hidden cells' search reads the same map and tiles).
    depths = domain.kept_depth_maps()
    node_tiles = _node_tiles(domain)
    states = _whole_tiles(domain, grids, depths)
    mine = winner >= 0
    # (winner -1, nobody's: a negative index into the last row, masked out by mine)
    state = np.take(states.ravel(), winner * states.shape[1] + node_tiles)
    settled = mine & (state == 1)
    mixed = np.flatnonzero(mine & (state < 0))
    by_gen = mixed[np.argsort(winner[mixed], kind="stable")]
    bounds = np.searchsorted(winner[by_gen], np.arange(k_gens + 1))
    for k in range(k_gens):
        cells = by_gen[bounds[k]:bounds[k + 1]]
        if len(cells):
            settled[cells] = domain.visible_each(grids[k], centers[cells], depths)
        own_snap = snap_best[k][0]
        settled[own_snap[winner[own_snap] == k]] = True
    dist[1:first] = np.where(settled, best, np.inf)
    pred[1:first] = np.where(settled, first + winner, -9999)
    label[1:first] = np.where(settled, winner, -1)
    hidden = np.flatnonzero(free & ~settled)
    if len(hidden):
        _search_hidden(domain, local, hidden, settled, dist, pred, label, grids, biases,
                       snap_best, (depths, states, node_tiles[hidden], winner[hidden]))
    return dist, pred, label


def _whole_tiles(domain: CoverageDomain, grids: np.ndarray, depths: DepthMaps) -> np.ndarray:
    """``(k, tiles) int8``: :meth:`~coverage_ros.core.geodesic.sight.LineOfSight.
    sight_tiles_whole` from each generator at ``grids (k, 2)`` (its depth map, kept in
    ``depths``, serves the point tests too)."""
    return np.stack([domain.sight_tiles_whole(g, depths) for g in grids])


def _node_tiles(domain: CoverageDomain) -> np.ndarray:
    """``(H * W,)`` every node's line-of-sight tile (row-major tiles of SIGHT_TILE cells, as
    :func:`~coverage_ros.core.geodesic.tangents.sight_tiles` numbers them); memoized."""
    key = ("node_tiles", SIGHT_TILE)
    tiles: np.ndarray | None = domain._cache.get(key)
    if tiles is None:
        H, W = domain.shape
        nx = -(-W // SIGHT_TILE)
        tiles = ((np.arange(H) // SIGHT_TILE)[:, None] * nx
                 + (np.arange(W) // SIGHT_TILE)[None, :]).ravel()
        domain._cache[key] = tiles
    return tiles


def _search_hidden(domain: CoverageDomain, local: LocalGraph, hidden: np.ndarray,
                   settled: np.ndarray, dist: np.ndarray, pred: np.ndarray, label: np.ndarray,
                   grids: np.ndarray, biases: np.ndarray,
                   snap_best: list[tuple[np.ndarray, np.ndarray]],
                   sight: tuple[DepthMaps, np.ndarray, np.ndarray, np.ndarray]) -> None:
    """Dijkstra over the hidden cells from their settled neighbours and from every generator's
    own seeds among them (in line of sight, or snap edges); fills the arrays in place.
    ``sight``: the depth maps made so far, every generator's tile states (:func:`_whole_tiles`),
    the hidden cells' line-of-sight tiles and their straight-line winners (each hidden from its
    own: no line from it is tested)."""
    n = local.n
    first = n + 1
    res = domain.resolution
    k_gens = len(grids)
    nb_table, cost_table = domain.graph.edge_table  # (n, K) node ids, n where no edge
    # A visibility domain's graph is the grid's own (no chart edges): its edge table serves.
    to_hidden = nb_table[hidden]
    settled_x = np.append(settled, False)  # (index n: the table's "no edge")
    mark = np.zeros(n + 1, dtype=bool)
    mark[to_hidden[settled_x[to_hidden]]] = True
    border = np.flatnonzero(mark[:n])
    sub = np.concatenate([hidden, border])  # sub index -> node index
    pos = np.full(n + 1, -1, dtype=np.int32)
    pos[sub] = np.arange(len(sub), dtype=np.int32)
    m = len(sub)
    # Hidden rows: their graph edges within the sub-graph; border rows: edges into hidden
    # cells. Rows are selected row-major, so they stay in order (CSR built directly).
    uniform = domain.graph.offset_costs  # (one cost per offset: no gather of the costs)
    n_hidden = len(hidden)
    counts, cols, vals = [], [], []
    for start, to in ((hidden, to_hidden), (border, nb_table[border])):
        at = pos[to]
        # (hidden rows: every edge, all to hidden or border cells; border rows: to hidden)
        inside = at >= 0 if start is hidden else at.view(np.uint32) < n_hidden
        counts.append(inside.sum(axis=1))
        cols.append(at[inside])
        vals.append(cost_table[start][inside] if uniform is None
                    else np.broadcast_to(uniform, to.shape)[inside])
    rows = (np.concatenate(counts), np.concatenate(cols), np.concatenate(vals))
    # One virtual source per generator: to its border cells at their settled distance, and to
    # the hidden cells it snaps to or sees (at its snap / straight-line cost).
    to_border, snap_cost = [], []
    for k in range(k_gens):
        mine = border[label[border + 1] == k]
        to_border.append((pos[mine], dist[mine + 1]))
        snap_nodes, snap_costs = snap_best[k]
        hid = (pos[snap_nodes] >= 0) & ~settled[snap_nodes]  # hidden: pos < len(hidden)
        snap_cost.append(_least(pos[snap_nodes[hid]], snap_costs[hid]))
    size = m + k_gens
    sources = np.arange(m, size)
    # First without the straight lines into hidden cells: the distances found are lengths of
    # real paths, so a straight-line seed that is no shorter cannot change any distance (nor,
    # being strictly longer, any label or parent): only the others need a line-of-sight test,
    # which is most of this search's cost (a team bunched in a corner of depot leaves half of
    # the map hidden from its nearest robot; a few hundred cells then get a shorter line).
    d, p, src = dijkstra(_graph(rows, to_border, snap_cost, size), directed=True,
                         indices=sources, min_only=True, return_predecessors=True)
    upper = d[:len(hidden)]
    hc = local.centers[hidden]
    depths, states, tiles, winners = sight
    # The hidden cells by line-of-sight tile, and per tile the longest path found into it: a
    # tile whose nearest point is farther from a generator in a straight line than every path
    # found into the tile cannot give that generator a shorter line (nor need its test).
    small = tiles.astype(np.uint16) if len(tiles) and tiles.max() < 1 << 16 else tiles
    by_tile = np.argsort(small, kind="stable")  # (16-bit keys: a radix sort)
    present, starts, per_tile = np.unique(tiles[by_tile], return_index=True, return_counts=True)
    longest = np.maximum.reduceat(upper[by_tile], starts)
    won = winners[by_tile]
    alone = np.where(np.minimum.reduceat(won, starts) == np.maximum.reduceat(won, starts),
                     np.maximum.reduceat(won, starts), -1)  # (a tile of one winner's cells)
    nx = -(-domain.shape[1] // SIGHT_TILE)
    tx0, ty0 = (present % nx) * float(SIGHT_TILE), (present // nx) * float(SIGHT_TILE)
    fresh: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    tiled = (by_tile, starts, per_tile, longest, tx0, ty0)
    for k in range(k_gens):  # (cells in tiles hidden whole from the generator drop out first)
        may = _may_be_shorter(tiled, grids[k], biases[k], res)
        may = may[alone[may] != k]
        if len(may) == 0:
            continue
        state = states[k, present[may]]
        may, state = may[state != 0], state[state != 0]
        if len(may) == 0:
            continue
        near = by_tile[_ranges(starts[may], per_tile[may])]
        e = np.hypot(hc[near, 0] - grids[k, 0], hc[near, 1] - grids[k, 1]) * res + biases[k]
        keep = (e <= upper[near] + 1e-9) & (winners[near] != k)
        better, e = near[keep], e[keep]
        seen = np.repeat(state, per_tile[may])[keep] == 1  # (tiles seen whole)
        test = np.flatnonzero(~seen)  # (the others: mixed)
        seen[test] = domain.visible_each(grids[k], hc[better[test]], depths)
        if seen.any():
            fresh[k] = (better[seen], e[seen])
    if fresh:  # (a line no shorter than the path found changes nothing: the first stands)
        _improve(domain, hidden, hc, (d, p, src), fresh, grids, biases, tiled)
    h = np.arange(len(hidden))
    reached = np.isfinite(d[h])
    lid = hidden[h[reached]] + 1
    dist[lid] = d[h[reached]]
    label[lid] = src[h[reached]] - m
    parent = p[h[reached]]
    from_source = parent >= m
    mapped = np.where(from_source, first + (parent - m), sub[np.minimum(parent, m - 1)] + 1)
    pred[lid] = mapped


def _may_be_shorter(tiled: tuple[np.ndarray, ...], grid: np.ndarray, bias: float,
                    res: float) -> np.ndarray:
    """Indices into the hidden cells' tiles (``tiled``: the cells by tile, each tile's first
    of them, count, longest path found into it and corner) of those whose nearest point is no
    farther from a generator at ``grid`` in a straight line than that longest path."""
    _, _, _, longest, tx0, ty0 = tiled
    gx, gy = grid
    gap = np.hypot(np.maximum(np.maximum(tx0 - gx, gx - tx0 - SIGHT_TILE), 0.0),
                   np.maximum(np.maximum(ty0 - gy, gy - ty0 - SIGHT_TILE), 0.0))
    may: np.ndarray = np.flatnonzero(gap * (res * (1.0 - 1e-12)) + bias <= longest + 1e-9)
    return may


def _improve(domain: CoverageDomain, hidden: np.ndarray, hc: np.ndarray,
             found: tuple[np.ndarray, np.ndarray, np.ndarray],
             fresh: dict[int, tuple[np.ndarray, np.ndarray]], grids: np.ndarray,
             biases: np.ndarray, tiled: tuple[np.ndarray, ...]) -> None:
    """Add the straight lines into hidden cells found shorter than the first search's paths
    (``fresh``: per generator, hidden indices and costs) to that search's results ``found``
    (distances, parents, sources over the sub-graph of the hidden cells, then their border,
    then the sources; changed in place). A path from such a seed is at least the straight
    line from its generator, so it can only be shorter where that line is shorter than the
    path found - and so is every node before it on the path: one search from the new seeds
    over those cells alone, each cell then taking the shorter of its two distances, is the
    search with every seed at once. A path from a seed ``s`` (cost ``e_s``) to a cell ``q``
    is no shorter than ``e_s + |q - s|``, nor is it anywhere on the way: only the cells whose
    path found is no shorter than that bound, least over blocks of seeds and taken box to
    box for the cell's tile, are searched (on depot about a fifth of the hidden cells)."""
    d, p, src = found
    n_hidden = len(hidden)
    m = len(d) - len(grids)  # the sub-graph's nodes; its sources follow
    by_tile, starts, per_tile, longest, tx0, ty0 = tiled
    scale = domain.resolution * (1.0 - 1e-12)  # [m per cell] (rounding: the bound stays below)
    seeds = np.concatenate([idx for idx, _ in fresh.values()])
    boxes, least = _seed_blocks(hc[seeds], np.concatenate([e for _, e in fresh.values()]))
    gap = np.hypot(_gap(tx0[:, None], tx0[:, None] + SIGHT_TILE, boxes[None, :, 0],
                        boxes[None, :, 2]),
                   _gap(ty0[:, None], ty0[:, None] + SIGHT_TILE, boxes[None, :, 1],
                        boxes[None, :, 3]))
    bound = (least[None, :] + gap * scale).min(axis=1)  # [m] per tile
    may = np.flatnonzero(bound <= longest + 1e-9)
    cells = by_tile[_ranges(starts[may], per_tile[may])]
    # (then cell by cell against its own path found; hidden indices, the sub-graph's first
    # nodes, in order)
    cells = np.sort(cells[np.repeat(bound[may], per_tile[may]) <= d[cells] + 1e-9])
    m2 = len(cells)
    at = np.full(n_hidden + 1, -1, dtype=np.int32)  # hidden index -> index among cells
    at[cells] = np.arange(m2, dtype=np.int32)
    nb_table, cost_table = domain.graph.edge_table
    nodes = hidden[cells]
    cell_of = np.full(len(nb_table), -1, dtype=np.int32)  # node -> index among cells
    cell_of[nodes] = np.arange(m2, dtype=np.int32)
    to = nb_table[nodes]
    to_cell = cell_of[to]
    inside = to_cell >= 0
    uniform = domain.graph.offset_costs
    rows = (inside.sum(axis=1), to_cell[inside], cost_table[nodes][inside] if uniform is None
            else np.broadcast_to(uniform, to.shape)[inside])
    gens = np.array(list(fresh), dtype=np.int64)
    none = (np.zeros(0, dtype=np.int32), np.zeros(0))
    d2, p2, src2 = dijkstra(
        _graph(rows, [none] * len(gens), [(at[c], e) for c, e in fresh.values()],
               m2 + len(gens)),
        directed=True, indices=np.arange(m2, m2 + len(gens)), min_only=True,
        return_predecessors=True)
    shorter = np.flatnonzero(d2[:m2] < d[cells])
    idx = cells[shorter]
    d[idx] = d2[shorter]
    parent = p2[shorter]
    p[idx] = np.where(parent >= m2, m + gens[np.maximum(parent - m2, 0)],
                      cells[np.minimum(np.maximum(parent, 0), max(m2 - 1, 0))])
    src[idx] = m + gens[src2[shorter] - m2]


def _seed_blocks(points: np.ndarray, costs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The seeds at ``points`` [cells] by blocks of SIGHT_TILE x SIGHT_TILE cells: each
    block's bounding box of its seeds ``(x0, y0, x1, y1)`` and its least cost."""
    block = np.floor(points / SIGHT_TILE).astype(np.int64)
    key = block[:, 1] * (int(block[:, 0].max()) + 1) + block[:, 0]  # (cells >= 0)
    order = np.argsort(key, kind="stable")
    first = np.flatnonzero(np.diff(key[order], prepend=-1))
    pts = points[order]
    boxes = np.column_stack([np.minimum.reduceat(pts[:, 0], first),
                             np.minimum.reduceat(pts[:, 1], first),
                             np.maximum.reduceat(pts[:, 0], first),
                             np.maximum.reduceat(pts[:, 1], first)])
    least: np.ndarray = np.minimum.reduceat(costs[order], first)
    return boxes, least


def _gap(lo: np.ndarray, hi: np.ndarray, lo2: np.ndarray, hi2: np.ndarray) -> np.ndarray:
    """The gap between the intervals ``[lo, hi]`` and ``[lo2, hi2]`` (0 where they meet)."""
    gap: np.ndarray = np.maximum(np.maximum(lo2 - hi, lo - hi2), 0.0)
    return gap


def _ranges(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The indices ``starts[i] .. starts[i] + counts[i] - 1`` of every range, in order."""
    ends = np.cumsum(counts)
    indices: np.ndarray = np.arange(ends[-1] if len(ends) else 0) + np.repeat(
        starts - (ends - counts), counts)
    return indices


def _least(cells: np.ndarray, costs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each of ``cells`` once, at the least of its ``costs``."""
    if len(cells) == 0:
        return cells.astype(np.int32), costs
    unique, inverse = np.unique(cells, return_inverse=True)
    least = np.full(len(unique), np.inf)
    np.minimum.at(least, inverse, costs)
    return unique.astype(np.int32), least


def _graph(rows: tuple[np.ndarray, np.ndarray, np.ndarray],
           to_border: list[tuple[np.ndarray, np.ndarray]],
           seeds: list[tuple[np.ndarray, np.ndarray]], size: int) -> csr_matrix:
    """The sub-graph's ``rows`` in order (edge counts per row, their columns and costs), then
    per generator k a source row to its border cells (``to_border[k]``: sub indices and costs)
    and to its hidden seed cells (``seeds[k]``: hidden indices, each once, and costs); built as
    CSR directly (no edge appears twice, so there is nothing to sum or sort)."""
    counts, cols, vals = [rows[0]], [rows[1]], [rows[2]]
    for (b_cols, b_vals), (to, cost) in zip(to_border, seeds, strict=True):
        counts.append(np.array([len(b_cols) + len(to)]))
        cols += [b_cols, to]
        vals += [np.maximum(b_vals, 1e-12), np.maximum(cost, 1e-12)]  # (0: no edge)
    indptr = np.zeros(size + 1, dtype=np.int32)
    np.cumsum(np.concatenate(counts), out=indptr[1:])
    return csr_matrix((np.concatenate(vals), np.concatenate(cols), indptr), shape=(size, size))
