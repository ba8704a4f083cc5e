"""Slow, obvious implementations used to check and to benchmark the fast ones.

* :func:`paper_cell` - the pseudo-code "Tessellation and Control Computation" of Bhattacharya et
  al. 2014 (section 4), decentralized form, written straightforwardly with :mod:`heapq`: a
  multi-source wavefront ordered by power distance, the control covector integrated during the
  search with the first-edge tangent, and the early exit once no unexpanded vertex of the own cell
  is left. This is the baseline of ``scripts/bench_core``.
* :func:`obvious_cell` - the definition, evaluated the obvious way: one full heapq Dijkstra per
  generator (sources as in the fast code), labels by the smallest power distance, tangents by
  walking each cell's parent chain in Python. The parity tests compare
  :func:`coverage_ros.core.geodesic.cell.geodesic_cell` against it.

Both accept the same inputs as the fast code (a :class:`CoverageDomain` and generators) and
use the domain's graph through plain Python adjacency lists built once per domain.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.geodesic.cell import LOOKAHEAD_CELLS
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tessellation import Generator, resolve_method


@dataclass(frozen=True)
class ReferenceCell:
    nodes: np.ndarray  # sorted node ids of the own cell
    distances: np.ndarray  # g at those nodes
    mass: float
    cost: float
    covector: np.ndarray  # (2,) I_k, grid axes
    next_vertex: int  # node id chosen by line 32 of the pseudo-code
    expanded: int  # vertices taken off the heap


def adjacency(domain: CoverageDomain) -> list[list[tuple[int, float]]]:
    """Plain Python adjacency lists ``adj[node] = [(neighbour, cost), ...]`` (cached)."""
    key = "py_adjacency"
    if key not in domain._cache:
        csr = domain.graph.csr
        indptr, indices, data = csr.indptr.tolist(), csr.indices.tolist(), csr.data.tolist()
        domain._cache[key] = [list(zip(indices[indptr[v]:indptr[v + 1]],
                                       data[indptr[v]:indptr[v + 1]], strict=True))
                              for v in range(csr.shape[0])]
    adj: list[list[tuple[int, float]]] = domain._cache[key]
    return adj


def _py_tables(domain: CoverageDomain) -> tuple[list[float], list[float], list[float]]:
    key = "py_tables"
    if key not in domain._cache:
        W = domain.shape[1]
        n = domain.graph.num_nodes
        xs = [(v % W + 0.5) for v in range(n)]
        ys = [(v // W + 0.5) for v in range(n)]
        domain._cache[key] = (xs, ys, domain.mass_element.ravel().tolist())
    tables: tuple[list[float], list[float], list[float]] = domain._cache[key]
    return tables


def paper_cell(domain: CoverageDomain, own: Generator, others: Sequence[Generator],
               ) -> ReferenceCell:
    """Bhattacharya et al.'s pseudo-code for robot ``own`` (decentralized; see module
    docstring)."""
    adj = adjacency(domain)
    xs, ys, wdA = _py_tables(domain)
    res = domain.resolution
    N = domain.graph.num_nodes
    gens = [own, *others]
    INF = math.inf
    g = [INF] * N  # shortest distances
    rho = [INF] * N  # power distances
    tau = [-1] * N  # tessellation
    nu = [-1] * N  # first vertex after the generator on the shortest path (-1: none yet)
    done = [False] * N
    heap: list[tuple[float, int]] = []
    own_open = set()
    # Per generator: its chart position P(p_l) and metric tensor eta(P(p_l)) (line 21).
    P = [tuple(float(v) for v in domain.to_grid(gen.position)[0]) for gen in gens]
    Ms = [tuple(float(v) for v in domain.metric_at(np.array([p]))[0].ravel()) for p in P]
    covectors = [[0.0, 0.0] for _ in gens]  # line 9: I_l
    # Generators are virtual vertices joined to the cells around them (lines 5-11).
    for k, gen in enumerate(gens):
        nodes, costs, _ = domain.snap(gen.position)
        r2 = gen.weight * gen.weight
        for v, c in zip(nodes.tolist(), costs.tolist(), strict=True):
            p = c * c - r2
            if p < rho[v]:
                g[v], rho[v], tau[v], nu[v] = c, p, k, v
                heapq.heappush(heap, (p, v))
                if k == 0:
                    own_open.add(v)
                else:
                    own_open.discard(v)
    expanded = 0
    while heap:  # line 13
        p, q = heapq.heappop(heap)
        if done[q] or p > rho[q]:
            continue
        if not own_open:  # the own tessellum is complete: stop (decentralized form)
            break
        done[q] = True
        expanded += 1
        lab = tau[q]
        s = nu[q]
        if lab == 0:
            own_open.discard(q)
        # lines 20-21: I_l += g(q) * M z / sqrt(z' M z) * w(q) * sqrt(det M), z = P(s) - P(p_l)
        px, py = P[lab]
        m00, m01, m10, m11 = Ms[lab]
        zx, zy = (xs[s] - px) * res, (ys[s] - py) * res
        mzx, mzy = m00 * zx + m01 * zy, m10 * zx + m11 * zy
        norm = math.sqrt(zx * mzx + zy * mzy)
        if norm > 0:
            f = g[q] * wdA[q] / norm  # wdA already holds w(q) * sqrt(det eta(q)) * cell area
            covectors[lab][0] += f * mzx
            covectors[lab][1] += f * mzy
        r2 = gens[lab].weight ** 2
        gq = g[q]
        # The relaxation of lines 22-30 repeats lines 8-10 inline on purpose: this is the
        # benchmark's baseline, and a helper call per edge would slow it (and flatter the
        # fast code's speedup).
        for w, c in adj[q]:  # lines 22-30
            if done[w]:
                continue
            g2 = gq + c
            p2 = g2 * g2 - r2
            if p2 < rho[w]:
                g[w], rho[w], tau[w], nu[w] = g2, p2, lab, s
                heapq.heappush(heap, (p2, w))
                if lab == 0:
                    own_open.add(w)
                else:
                    own_open.discard(w)
    I0, I1 = covectors[0]
    nodes = np.array(sorted(v for v in range(N) if done[v] and tau[v] == 0), dtype=np.int64)
    dist = np.array([g[v] for v in nodes])
    w_arr = domain.mass_element.ravel()[nodes]
    covector = np.array([I0, I1])
    return ReferenceCell(nodes, dist, float(w_arr.sum()),
                         float(((dist ** 2 - own.weight ** 2) * w_arr).sum()), covector,
                         _best_neighbour(domain, own, covector), expanded)


def _best_neighbour(domain: CoverageDomain, own: Generator, covector: np.ndarray) -> int:
    """Line 32: the neighbour vertex of the robot's vertex best aligned with I_k."""
    base = int(domain.snap(own.position)[0][0])
    best, score = base, 0.0
    for v, _ in adjacency(domain)[base]:
        z = domain.chart_displacement(domain.node_centers(np.array([base])),
                                      domain.node_centers(np.array([v])))[0]
        if float(z @ covector) > score:
            best, score = v, float(z @ covector)
    return best


def _dijkstra(adj: list[list[tuple[int, float]]], sources: list[tuple[int, float]], n: int
              ) -> tuple[list[float], list[int]]:
    """Plain heapq Dijkstra from several (node, initial distance) seeds; parent -1 = seed."""
    dist = [math.inf] * n
    parent = [-2] * n
    heap: list[tuple[float, int]] = []
    for v, d in sources:
        if d < dist[v]:
            dist[v], parent[v] = d, -1
            heapq.heappush(heap, (d, v))
    done = [False] * n
    while heap:
        d, v = heapq.heappop(heap)
        if done[v]:
            continue
        done[v] = True
        for w, c in adj[v]:
            nd = d + c
            if nd < dist[w]:
                dist[w], parent[w] = nd, v
                heapq.heappush(heap, (nd, w))
    return dist, parent


def obvious_cell(domain: CoverageDomain, own: Generator, others: Sequence[Generator],
                 method: str = "auto") -> ReferenceCell:
    """The cell and control by the definition (see module docstring)."""
    method = resolve_method(domain, method)
    adj = adjacency(domain)
    N = domain.graph.num_nodes
    gens = [own, *others]
    free_nodes = np.flatnonzero(domain.free.ravel())
    centers = domain.node_centers(free_nodes)
    fields = []
    for gen in gens:
        if method == "visibility":
            nodes, costs, _ = domain.seeds(gen.position, free_nodes, centers, math.inf)
        else:
            nodes, costs, _ = domain.snap(gen.position)
        fields.append(_dijkstra(adj, list(zip(nodes.tolist(), costs.tolist(), strict=True)), N))
    own_dist, own_parent = fields[0]

    def wins(v: int) -> bool:
        mine = own_dist[v] ** 2 - own.weight ** 2
        return all(not (d[v] ** 2 - gen.weight ** 2 < mine)
                   for (d, _), gen in zip(fields[1:], others, strict=True))

    cell = []
    for v in range(N):
        if not domain.graph.free.flat[v] or own_dist[v] == math.inf or not wins(v):
            continue
        a = own_parent[v]  # the whole shortest path must lie in the cell (star-shaped)
        while a >= 0 and wins(a):
            a = own_parent[a]
        if a < 0:
            cell.append(v)
    nodes = np.array(cell, dtype=np.int64)
    dist = np.array([own_dist[v] for v in cell])
    w_arr = domain.mass_element.ravel()[nodes]
    p = domain.to_grid(own.position)[0]
    look = LOOKAHEAD_CELLS * domain.graph.max_edge_cost
    M = domain.metric_at(p[None])[0]
    cov = np.zeros(2)
    W = domain.shape[1]
    for v, gv, wv in zip(cell, dist.tolist(), w_arr.tolist(), strict=True):
        # Walk from v toward the robot: to the first vertex after the source, or (lookahead)
        # to the last vertex within the look-ahead distance.
        a = v
        while own_parent[a] >= 0 and not (method == "lookahead" and own_dist[a] <= look):
            a = own_parent[a]
        z = domain.chart_displacement(p, np.array([a % W + 0.5, a // W + 0.5]))
        mz = M @ z
        norm = math.sqrt(float(z @ mz))
        if norm > 1e-12:
            cov += gv * wv / norm * mz
    return ReferenceCell(nodes, dist, float(w_arr.sum()),
                         float(((dist ** 2 - own.weight ** 2) * w_arr).sum()), cov,
                         _best_neighbour(domain, own, cov), len(cell))
