"""The pruned, cached search graph behind the decentralized cell update.

To find its own cell, robot i needs shortest-path distances from itself over its *own ball*
(radius L) and, from each neighbour j, along the paths by which j could reach a point of the own
ball first. j can claim q only if g_j(q) < L_j = sqrt(L^2 - R_i^2 + R_j^2), so only points of
``Q_j = ball(p_i, L) & ball(p_j, L_j)`` (balls of the metric's Euclidean lower bound
``lam |x - y|``, lam = 1 for maps), and every point x of such a path satisfies ::

    lam (|x - p_j| + dist(x, Q_j)) <= L_j                ("cone" of j)

Searching only the own ball and the cones is exact.

Regions are computed on a global grid of ``BLOCK x BLOCK`` cell blocks (conservatively), and
the search graph of a region is kept in a :class:`SearchCache`: while the region a robot needs
stays inside the cached one (robots move centimetres between updates), only the rows of the
virtual sources are rewritten. The cached region is built with a margin for that purpose.

Local node ids: 0 is a dead-end *sink* that every missing or out-of-region edge points to,
region nodes are 1..n (``global_nodes[i - 1]``), virtual sources follow.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix

from coverage_ros.core.geodesic.domain import CoverageDomain

#: [cells] side of the blocks on which search regions are computed.
BLOCK = 4
#: [cells] extra reach of a cached region, so that the next updates of a moving robot fit.
CACHE_MARGIN_CELLS = 3.0
#: A cached region is rebuilt once the search radius shrank by more than this factor (a
#: larger region makes the neighbours' searches expand further than necessary).
CACHE_MAX_OVERSIZE = 1.35
#: Most connections a virtual source has (its cell and three of the 2x2 block around it).
MAX_CONNECTIONS = 4
#: A search region holding at least this share of the map's free cells is the whole map.
WHOLE_SHARE = 0.5
#: The same share for a search that settles what is in line of sight of the sources first
#: (``visibility`` sources, equal weights: cell.py). From about a third of the map on, its
#: limited search (every neighbour's source joined to the cells it sees) costs as much as the
#: whole-map search, which settles the cells in sight without searching and never has to grow
#: (README, "A robot's first update").
SIGHT_WHOLE_SHARE = 0.35


@dataclass
class LocalGraph:
    blocks: np.ndarray  # (Hb, Wb) bool, global block grid: the region this graph covers
    global_nodes: np.ndarray  # (n,) int64, sorted
    centers: np.ndarray  # (n, 2) grid coordinates of the region nodes
    seedable: np.ndarray  # (n,) bool: free nodes (a source may be joined to them)
    row_ptr: np.ndarray  # (H + 1,) index of the first region node of each grid row
    nb: np.ndarray  # (n, K) int32 local neighbour ids along the grid offsets (0 = sink)
    edge: np.ndarray  # (n, K) bool: the full graph has this edge
    region_indptr: np.ndarray  # (n + 2,) int32 row pointers of the sink and region rows
    indices: np.ndarray  # int32 buffer: the region rows' entries, then room for sources
    data: np.ndarray  # float64 buffer, same layout
    n: int
    covers_all: bool
    built_for: tuple[np.ndarray, np.ndarray] | None = None  # (centers, radii) of the build

    def rows_slice(self, row0: float, row1: float) -> slice:
        """Index range (into the region nodes) of the grid rows ``row0 .. row1``."""
        H = len(self.row_ptr) - 1
        a = int(np.clip(np.floor(row0), 0, H))
        b = int(np.clip(np.floor(row1) + 1, 0, H))
        return slice(int(self.row_ptr[a]), int(self.row_ptr[max(a, b)]))

    def local_of(self, nodes: np.ndarray) -> np.ndarray:
        """Local ids (1..n) of global ``nodes``; 0 for nodes outside the region."""
        if self.n == 0:
            return np.zeros(len(nodes), dtype=np.int64)
        lid = np.minimum(np.searchsorted(self.global_nodes, nodes), self.n - 1)
        return np.where(self.global_nodes[lid] == nodes, lid + 1, 0)

    def with_sources(self, rows: list[tuple[np.ndarray, np.ndarray]]) -> csr_matrix:
        """The search graph with virtual sources appended (rows n + 1, ...); each source is
        ``(local ids, edge costs)`` of the nodes it is joined to."""
        n = self.n
        nnz = int(self.region_indptr[-1])
        need = nnz + sum(len(lid) for lid, _ in rows)
        if len(self.indices) < need:
            self.indices = np.concatenate([self.indices[:nnz],
                                           np.zeros(need - nnz + 64, np.int32)])
            self.data = np.concatenate([self.data[:nnz], np.zeros(need - nnz + 64)])
        pos = nnz
        counts = []
        for lid, costs in rows:
            m = len(lid)
            self.indices[pos:pos + m] = lid
            # scipy treats explicit zeros as "no edge": a source on a cell centre costs 1e-12.
            self.data[pos:pos + m] = np.maximum(costs, 1e-12)
            pos += m
            counts.append(m)
        total = n + 1 + len(rows)
        indptr = np.empty(total + 1, dtype=np.int32)
        indptr[:n + 2] = self.region_indptr
        indptr[n + 2:] = nnz + np.cumsum(counts, dtype=np.int32)
        return csr_matrix((self.data[:pos], self.indices[:pos], indptr), shape=(total, total))


class SearchCache:
    """One robot's reusable search graph and last cell radius. Not thread-safe."""

    def __init__(self) -> None:
        self.graph: LocalGraph | None = None
        self.cell_radius: float | None = None
        #: the domain's whole-map search kept when this robot's last update ended
        self.whole_search: object | None = None
        self.hits = 0
        self.misses = 0


def lens_distance(x: np.ndarray, y: np.ndarray, a: np.ndarray, ra: float, b: np.ndarray,
                  rb: float) -> np.ndarray:
    """Distance from points ``(x, y)`` (broadcastable arrays) to the intersection of the discs
    ``(a, ra)`` and ``(b, rb)`` (0 inside it; inf if it is empty)."""
    d = float(np.hypot(*(b - a)))
    ax, ay = x - a[0], y - a[1]
    bx, by = x - b[0], y - b[1]
    da = np.hypot(ax, ay)
    db = np.hypot(bx, by)
    if d >= ra + rb:
        return np.full(np.broadcast(x, y).shape, np.inf)
    if d <= abs(ra - rb):  # one disc inside the other: the smaller one
        gap: np.ndarray = np.maximum(da - ra, 0.0) if ra <= rb else np.maximum(db - rb, 0.0)
        return gap
    u = (b - a) / d
    t0 = (d * d + ra * ra - rb * rb) / (2.0 * d)
    h = np.sqrt(max(ra * ra - t0 * t0, 0.0))
    cx, cy = a[0] + t0 * u[0], a[1] + t0 * u[1]
    corners = np.minimum(np.hypot(x - (cx - h * u[1]), y - (cy + h * u[0])),
                         np.hypot(x - (cx + h * u[1]), y - (cy - h * u[0])))
    with np.errstate(invalid="ignore", divide="ignore"):
        # Nearest point of circle a (valid if it lies in disc b), and vice versa.
        pa_x, pa_y = a[0] + ra * ax / da, a[1] + ra * ay / da
        ok_a = (da > ra) & ((pa_x - b[0]) ** 2 + (pa_y - b[1]) ** 2 <= rb * rb)
        pb_x, pb_y = b[0] + rb * bx / db, b[1] + rb * by / db
        ok_b = (db > rb) & ((pb_x - a[0]) ** 2 + (pb_y - a[1]) ** 2 <= ra * ra)
    out = corners
    out = np.where(ok_a, np.minimum(out, da - ra), out)
    out = np.where(ok_b, np.minimum(out, db - rb), out)
    return np.where((da <= ra) & (db <= rb), 0.0, out)


def required_blocks(domain: CoverageDomain, centers: np.ndarray, radii: np.ndarray, L: float,
                    margin_cells: float = 0.0, enough: float = math.inf) -> np.ndarray:
    """``(Hb, Wb)`` bool over the global block grid: blocks that may hold a point of the own
    ball (generator 0, radius L) or of a cone (generators 1..; radii L_j), grown by
    ``margin_cells``. ``centers`` are grid coordinates. Returned early, a part of them, once
    the blocks found hold ``enough`` free cells (the caller then takes the whole map)."""
    H, W = domain.shape
    Hb, Wb = -(-H // BLOCK), -(-W // BLOCK)
    blocks = np.zeros((Hb, Wb), dtype=bool)
    lam_cells = domain.metric_lower_bound * domain.resolution
    slack = BLOCK * math.sqrt(0.5) + margin_cells  # [cells] block half-diagonal + margin
    own = centers[0]
    for k, (center, radius) in enumerate(zip(centers, radii, strict=True)):
        rad = radius / lam_cells + slack + 1.0
        a0 = max(0, int((center[1] - rad) // BLOCK))
        a1 = min(Hb, int((center[1] + rad) // BLOCK) + 1)
        b0 = max(0, int((center[0] - rad) // BLOCK))
        b1 = min(Wb, int((center[0] + rad) // BLOCK) + 1)
        if a0 >= a1 or b0 >= b1:
            continue
        ys = (np.arange(a0, a1) + 0.5) * BLOCK
        xs = (np.arange(b0, b1) + 0.5) * BLOCK
        dk = np.hypot(xs[None, :] - center[0], ys[:, None] - center[1])
        if k == 0:
            sub = (dk - slack) * lam_cells <= L
        else:
            # Both terms are 1-Lipschitz: over a block they are at least their value at the
            # block centre minus the slack each.
            dq = lens_distance(xs[None, :], ys[:, None], own, L / lam_cells, center,
                               radius / lam_cells)
            sub = (dk + dq - 2.0 * slack) * lam_cells <= radius
        blocks[a0:a1, b0:b1] |= sub
        if math.isfinite(enough) and _free_counts(domain)[blocks].sum() >= enough:
            break  # (blocks only grow: the whole region would hold enough too)
    return blocks


def build_local_graph(domain: CoverageDomain, blocks: np.ndarray | None) -> LocalGraph:
    """The search graph over the free cells of ``blocks`` (None: the whole domain, including
    any extra edges of a chart)."""
    graph = domain.graph
    H, W = graph.shape
    N = H * W
    K = len(graph.offsets)
    spare = MAX_CONNECTIONS * 16
    if blocks is None:
        Hb, Wb = -(-H // BLOCK), -(-W // BLOCK)
        csr = graph.csr
        nb_table, _ = graph.edge_table
        nb = np.where(nb_table[:N] == N, 0, nb_table[:N] + 1).astype(np.int32)
        all_nodes = np.arange(N, dtype=np.int64)
        return LocalGraph(
            blocks=np.ones((Hb, Wb), dtype=bool), global_nodes=all_nodes,
            centers=np.stack([all_nodes % W + 0.5, all_nodes // W + 0.5], axis=-1),
            seedable=graph.free.ravel().copy(),
            row_ptr=np.arange(0, N + 1, W, dtype=np.int64), nb=nb, edge=nb_table[:N] != N,
            region_indptr=np.concatenate([[0], csr.indptr]).astype(np.int32),
            indices=np.concatenate([csr.indices + 1, np.zeros(spare)]).astype(np.int32),
            data=np.concatenate([csr.data, np.zeros(spare)]), n=N, covers_all=True)
    rb, cb = np.nonzero(blocks)
    r0, r1 = int(rb.min()) * BLOCK, min(H, (int(rb.max()) + 1) * BLOCK)
    c0, c1 = int(cb.min()) * BLOCK, min(W, (int(cb.max()) + 1) * BLOCK)
    sub = blocks[r0 // BLOCK:-(-r1 // BLOCK), c0 // BLOCK:-(-c1 // BLOCK)]
    region = np.repeat(np.repeat(sub, BLOCK, axis=0), BLOCK, axis=1)[:r1 - r0, :c1 - c0]
    region = region & graph.free[r0:r1, c0:c1]
    global_nodes = (np.arange(r0, r1)[:, None] * W + np.arange(c0, c1)[None, :])[region]
    n = len(global_nodes)
    uniform = graph.uniform_costs
    if uniform is not None and not any(graph.wrap):
        # Euclidean: neighbour ids by arithmetic, edge existence from one bitmask per node.
        bits = graph.edge_bits[global_nodes]
        edge = ((bits[:, None] >> np.arange(K, dtype=bits.dtype)) & 1).astype(bool)
        nb_global = global_nodes[:, None] + graph.offset_steps[None, :]
        nb_global[~edge] = N
        costs = np.tile(uniform, n)
    else:
        nb_table, cost_table = graph.edge_table
        nb_global = nb_table[global_nodes]
        edge = nb_global != N
        costs = cost_table[global_nodes].ravel()
    lookup = np.zeros(N + 1, dtype=np.int32)
    lookup[global_nodes] = np.arange(1, n + 1, dtype=np.int32)
    nb = lookup[nb_global]
    indices = np.concatenate([nb.ravel(), np.zeros(spare, np.int32)])
    data = np.concatenate([costs, np.zeros(spare)])
    region_indptr = np.concatenate([[0], np.arange(0, (n + 1) * K, K)]).astype(np.int32)
    covers_all = bool(n == int(graph.free.sum()))
    centers = np.stack([global_nodes % W + 0.5, global_nodes // W + 0.5], axis=-1)
    row_ptr = np.searchsorted(global_nodes // W, np.arange(H + 1))
    return LocalGraph(blocks, global_nodes, centers, np.ones(n, dtype=bool), row_ptr, nb, edge,
                      region_indptr, indices, data, n, covers_all)


def _free_counts(domain: CoverageDomain) -> np.ndarray:
    """``(Hb, Wb)`` int: free cells in each block of the global block grid."""
    key = ("free_counts", BLOCK)
    if key not in domain._cache:
        H, W = domain.shape
        Hb, Wb = -(-H // BLOCK), -(-W // BLOCK)
        padded = np.zeros((Hb * BLOCK, Wb * BLOCK), dtype=np.int64)
        padded[:H, :W] = domain.graph.free
        domain._cache[key] = padded.reshape(Hb, BLOCK, Wb, BLOCK).sum(axis=(1, 3))
    counts: np.ndarray = domain._cache[key]
    return counts


def covers(graph: LocalGraph, centers: np.ndarray, radii: np.ndarray, lam_cells: float) -> bool:
    """Whether ``graph``'s region (built with the cache margin) contains the region for these
    generators: each term of the region's inequalities is 1-Lipschitz in the centres and radii,
    so moves and growth up to a third of the margin each are covered."""
    if graph.built_for is None:
        return False
    c0, r0 = graph.built_for
    if c0.shape != centers.shape:
        return False
    step = CACHE_MARGIN_CELLS / 3.0
    moved = np.hypot(*(centers - c0).T).max()
    grown = ((radii - r0) / lam_cells).max()
    shrunk = (radii[0] / r0[0]) < 1.0 / CACHE_MAX_OVERSIZE
    return bool(moved <= step and grown <= step and not shrunk)


def local_graph_for(domain: CoverageDomain, cache: SearchCache | None, centers: np.ndarray,
                    radii: np.ndarray, L: float, whole_share: float = WHOLE_SHARE) -> LocalGraph:
    """A search graph that covers the own ball and cones for search radius ``L``, reused
    from ``cache`` when the cached region already contains the required one; the whole map's
    graph when the region would hold ``whole_share`` of its free cells or more."""
    if not math.isfinite(L) or any(domain.graph.wrap):
        key = "whole_graph"
        g = domain._cache.get(key)
        if g is None:
            g = build_local_graph(domain, None)
            domain._cache[key] = g
        return g
    lam_cells = domain.metric_lower_bound * domain.resolution
    if cache is not None and cache.graph is not None and covers(cache.graph, centers, radii,
                                                                lam_cells):
        cache.hits += 1
        return cache.graph
    margin = CACHE_MARGIN_CELLS if cache is not None else 0.0
    counts = _free_counts(domain)
    whole = whole_share * counts.sum()
    blocks = required_blocks(domain, centers, radii, L, margin, enough=whole)
    if counts[blocks].sum() >= whole:
        # Most of the map: the domain's one whole-map graph, shared by every search on it (a
        # robot whose cell is most of the map keeps no copy of its own; a whole-map search
        # settles what is in line of sight first, see cell.py).
        if cache is not None:
            cache.misses += 1
            cache.graph = None
        return local_graph_for(domain, None, centers, radii, math.inf)
    g = build_local_graph(domain, blocks)
    g.built_for = (centers.copy(), radii.copy())
    if cache is not None:
        cache.misses += 1
        cache.graph = g
    return g
