"""The pruned, cached search graph behind the decentralized cell update.

To find its own cell, robot i needs shortest-path distances from itself over its *own ball*
(radius L) and, from each neighbour j, over the places where j could be closer than i: every
point of a path from p_j of length < L_j into the own ball satisfies ::

    lam |x - p_j| + max(0, lam |x - p_i| - L) <= L_j      ("lens" of j)

where ``lam |x - y|`` is a lower bound of the metric (lam = 1 for maps) and
``L_j = sqrt(L^2 - R_i^2 + R_j^2)``. Searching only the own ball and the lenses is exact.

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

from coverage_ros.core.domain import CoverageDomain

#: [cells] side of the blocks on which search regions are computed.
BLOCK = 4
#: [cells] extra reach of a cached region, so that the next updates of a moving robot fit.
CACHE_MARGIN_CELLS = 3.0
#: A cached region is reused only while it has at most this many times the blocks needed
#: (a larger region makes the neighbours' searches expand further than necessary).
CACHE_MAX_OVERSIZE = 1.35
#: Most connections a virtual source has (its cell and three of the 2x2 block around it).
MAX_CONNECTIONS = 4


@dataclass
class LocalGraph:
    blocks: np.ndarray  # (Hb, Wb) bool, global block grid: the region this graph covers
    global_nodes: np.ndarray  # (n,) int64, sorted
    nb: np.ndarray  # (n, K) int32 local neighbour ids (0 = sink)
    edge: np.ndarray  # (n, K) bool: the full graph has this edge
    indices: np.ndarray  # int32 buffer: n*K region entries, then room for sources
    data: np.ndarray  # float64 buffer, same layout
    n: int
    covers_all: bool

    def with_sources(self, sources: list[tuple[np.ndarray, np.ndarray]]) -> csr_matrix:
        """The search graph with these virtual sources (rows n + 1, ...) appended."""
        n, K = self.n, self.nb.shape[1]
        need = n * K + MAX_CONNECTIONS * len(sources)
        if len(self.indices) < need:
            grow = need + MAX_CONNECTIONS * 16
            self.indices = np.concatenate([self.indices[:n * K],
                                           np.zeros(grow - n * K, np.int32)])
            self.data = np.concatenate([self.data[:n * K], np.zeros(grow - n * K)])
        pos = n * K
        counts = []
        for nodes, costs in sources:
            if n:
                lid = np.minimum(np.searchsorted(self.global_nodes, nodes), n - 1)
                keep = self.global_nodes[lid] == nodes
            else:
                lid, keep = np.zeros(len(nodes), np.int64), np.zeros(len(nodes), bool)
            m = int(np.count_nonzero(keep))
            self.indices[pos:pos + m] = lid[keep] + 1
            # scipy treats explicit zeros as "no edge": a source on a cell centre costs 1e-12.
            self.data[pos:pos + m] = np.maximum(costs[keep], 1e-12)
            pos += m
            counts.append(m)
        total = n + 1 + len(sources)
        indptr = np.empty(total + 1, dtype=np.int32)
        indptr[0] = 0
        indptr[1:n + 2] = np.arange(0, (n + 1) * K, K, dtype=np.int32)
        indptr[n + 2:] = n * K + np.cumsum(counts, dtype=np.int32)
        return csr_matrix((self.data[:pos], self.indices[:pos], indptr), shape=(total, total))


class SearchCache:
    """One robot's reusable search graph and last cell radius. Not thread-safe."""

    def __init__(self) -> None:
        self.graph: LocalGraph | None = None
        self.cell_radius: float | None = None
        self.hits = 0
        self.misses = 0


def required_blocks(domain: CoverageDomain, centers: np.ndarray, radii: np.ndarray, L: float,
                    margin_cells: float = 0.0) -> np.ndarray:
    """``(Hb, Wb)`` bool over the global block grid: blocks that may hold a point of the own
    ball (generator 0, radius L) or of a lens (generators 1..; radii L_j), grown by
    ``margin_cells``. ``centers`` are grid coordinates."""
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
        dk = np.maximum(np.hypot(xs[None, :] - center[0], ys[:, None] - center[1]) - slack, 0.0)
        if k == 0:
            sub = dk * lam_cells <= L
        else:
            di = np.maximum(np.hypot(xs[None, :] - own[0], ys[:, None] - own[1]) - slack, 0.0)
            sub = (dk + np.maximum(di - L / lam_cells, 0.0)) * lam_cells <= radius
        blocks[a0:a1, b0:b1] |= sub
    return blocks


def build_local_graph(domain: CoverageDomain, blocks: np.ndarray | None) -> LocalGraph:
    """The search graph over the free cells of ``blocks`` (None: the whole domain)."""
    graph = domain.graph
    H, W = graph.shape
    N = H * W
    K = len(graph.offsets)
    if blocks is None:
        Hb, Wb = -(-H // BLOCK), -(-W // BLOCK)
        blocks = np.ones((Hb, Wb), dtype=bool)
        region = graph.free
        global_nodes = np.flatnonzero(region.ravel())
    else:
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
    spare = MAX_CONNECTIONS * 16
    indices = np.concatenate([nb.ravel(), np.zeros(spare, np.int32)])
    data = np.concatenate([costs, np.zeros(spare)])
    covers_all = bool(n == int(graph.free.sum()))
    return LocalGraph(blocks, global_nodes, nb, edge, indices, data, n, covers_all)


def local_graph_for(domain: CoverageDomain, cache: SearchCache | None, centers: np.ndarray,
                    radii: np.ndarray, L: float) -> LocalGraph:
    """A search graph that covers the own ball and lenses for search radius ``L``, reused
    from ``cache`` when the cached region already contains the required one."""
    if not math.isfinite(L) or any(domain.graph.wrap):
        key = "whole_graph"
        g = domain._cache.get(key)
        if g is None:
            g = build_local_graph(domain, None)
            domain._cache[key] = g
        return g
    need = required_blocks(domain, centers, radii, L)
    if cache is not None and cache.graph is not None:
        cached = cache.graph.blocks
        if (cached.shape == need.shape and not np.any(need & ~cached)
                and cached.sum() <= CACHE_MAX_OVERSIZE * need.sum()):
            cache.hits += 1
            return cache.graph
    margin = CACHE_MARGIN_CELLS if cache is not None else 0.0
    blocks = required_blocks(domain, centers, radii, L, margin) if margin else need
    g = build_local_graph(domain, blocks)
    if cache is not None:
        cache.misses += 1
        cache.graph = g
    return g
