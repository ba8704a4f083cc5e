"""Slow, obvious implementations used to check and to benchmark the fast ones.

* :func:`paper_cell` - the pseudo-code "Tessellation and Control Computation" of seed 000
  (section 4), decentralized form, written straightforwardly with :mod:`heapq`: a multi-source
  wavefront ordered by power distance, the control covector integrated during the search with
  the first-edge tangent, and the early exit once no unexpanded vertex of the own cell is left.
  This is the baseline of ``scripts/bench_core``.
* :func:`obvious_cell` - the definition, evaluated the obvious way: one full heapq Dijkstra per
  generator, labels by the smallest power distance, tangents by walking each cell's parent
  chain in Python with a direct line-of-sight test. The parity tests compare
  :func:`coverage_ros.core.tessellation.geodesic_cell` against it.

Both accept the same inputs as the fast code (a :class:`CoverageDomain` and generators) and
use the domain's graph through plain Python adjacency lists built once per domain.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.domain import CoverageDomain
from coverage_ros.core.tangents import CELL_HALF_DIAGONAL
from coverage_ros.core.tessellation import Generator


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
    return domain._cache[key]


def _py_tables(domain: CoverageDomain) -> tuple[list[float], list[float], list[float]]:
    key = "py_tables"
    if key not in domain._cache:
        W = domain.shape[1]
        n = domain.graph.num_nodes
        xs = [(v % W + 0.5) for v in range(n)]
        ys = [(v // W + 0.5) for v in range(n)]
        domain._cache[key] = (xs, ys, domain.mass_element.ravel().tolist())
    return domain._cache[key]


def paper_cell(domain: CoverageDomain, own: Generator, others: Sequence[Generator],
               ) -> ReferenceCell:
    """Seed 000's pseudo-code for robot ``own`` (decentralized; see module docstring)."""
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
    M = domain.metric_at(domain.to_grid(own.position))[0]
    m00, m01, m10, m11 = float(M[0, 0]), float(M[0, 1]), float(M[1, 0]), float(M[1, 1])
    sqrt_det = math.sqrt(m00 * m11 - m01 * m10)
    px, py = (float(v) for v in domain.to_grid(own.position)[0])
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
    I0 = I1 = 0.0
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
            # line 21: I += g(q) * M z / sqrt(z' M z) * w(q) * sqrt(det M)
            zx, zy = (xs[s] - px) * res, (ys[s] - py) * res
            mzx, mzy = m00 * zx + m01 * zy, m10 * zx + m11 * zy
            norm = math.sqrt(zx * mzx + zy * mzy)
            if norm > 0:
                f = g[q] * wdA[q] / norm
                I0 += f * mzx
                I1 += f * mzy
        r2 = gens[lab].weight ** 2
        gq = g[q]
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
    nodes = np.array(sorted(v for v in range(N) if done[v] and tau[v] == 0), dtype=np.int64)
    dist = np.array([g[v] for v in nodes])
    w_arr = domain.mass_element.ravel()[nodes]
    covector = np.array([I0, I1]) * 1.0
    del sqrt_det  # the area element is already in wdA (sqrt(det eta(q)) * res^2)
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


def _dijkstra(adj, sources: list[tuple[int, float]], n: int) -> tuple[list[float], list[int]]:
    """Plain heapq Dijkstra from several (node, initial distance) seeds; parent -1 = seed."""
    dist = [math.inf] * n
    parent = [-2] * n
    heap = []
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


def _line_of_sight(domain: CoverageDomain, a: tuple[float, float], b: tuple[float, float]) -> bool:
    """No blocked cell (a disc of radius CELL_HALF_DIAGONAL around its centre) comes closer
    to the segment a-b than its radius; checked against every blocked cell near the segment."""
    ax, ay = a
    bx, by = b
    lo_c, hi_c = int(math.floor(min(ax, bx))) - 1, int(math.floor(max(ax, bx))) + 1
    lo_r, hi_r = int(math.floor(min(ay, by))) - 1, int(math.floor(max(ay, by))) + 1
    H, W = domain.shape
    dx, dy = bx - ax, by - ay
    seg2 = dx * dx + dy * dy
    for r in range(max(lo_r, 0), min(hi_r, H - 1) + 1):
        for c in range(max(lo_c, 0), min(hi_c, W - 1) + 1):
            if domain.free[r, c]:
                continue
            cx, cy = c + 0.5, r + 0.5
            t = 0.0 if seg2 == 0 else max(0.0, min(1.0, ((cx - ax) * dx + (cy - ay) * dy) / seg2))
            if math.hypot(ax + t * dx - cx, ay + t * dy - cy) < CELL_HALF_DIAGONAL:
                return False
    return True


def obvious_cell(domain: CoverageDomain, own: Generator, others: Sequence[Generator],
                 tangent: str = "auto") -> ReferenceCell:
    """The cell and control by the definition (see module docstring)."""
    adj = adjacency(domain)
    N = domain.graph.num_nodes
    gens = [own, *others]
    fields = []
    for gen in gens:
        nodes, costs, _ = domain.snap(gen.position)
        fields.append(_dijkstra(adj, list(zip(nodes.tolist(), costs.tolist(), strict=True)), N))
    own_dist, own_parent = fields[0]
    cell = []
    for v in range(N):
        if not domain.graph.free.flat[v] or own_dist[v] == math.inf:
            continue
        mine = own_dist[v] ** 2 - own.weight ** 2
        if all(not (d[v] ** 2 - gen.weight ** 2 < mine)
               for (d, _), gen in zip(fields[1:], others, strict=True)):
            cell.append(v)
    nodes = np.array(cell, dtype=np.int64)
    dist = np.array([own_dist[v] for v in cell])
    w_arr = domain.mass_element.ravel()[nodes]
    p = tuple(float(v) for v in domain.to_grid(own.position)[0])
    if tangent == "auto":
        tangent = "visibility" if domain.graph.euclidean else "lookahead"
    look = 3.0 * domain.graph.max_edge_cost
    M = domain.metric_at(np.array([p]))[0]
    cov = np.zeros(2)
    W = domain.shape[1]
    in_cell = set(cell)
    for v, gv, wv in zip(cell, dist.tolist(), w_arr.tolist(), strict=True):
        centre = (v % W + 0.5, v // W + 0.5)
        # Walk from v toward the robot until the tangent criterion holds.
        a = v
        while True:
            ac = (a % W + 0.5, a // W + 0.5)
            par = own_parent[a]
            if tangent == "visibility" and _line_of_sight(domain, p, ac):
                break
            if tangent == "lookahead" and own_dist[a] <= look:
                break
            if tangent == "first_edge" and par == -1:
                break
            if par < 0 or par not in in_cell:
                break
            a = par
        anchor = (a % W + 0.5, a // W + 0.5)
        del centre
        z = domain.chart_displacement(np.array(p), np.array(anchor))
        mz = M @ z
        norm = math.sqrt(float(z @ mz))
        if norm > 1e-12:
            cov += gv * wv / norm * mz
    return ReferenceCell(nodes, dist, float(w_arr.sum()),
                         float(((dist ** 2 - own.weight ** 2) * w_arr).sum()), cov,
                         _best_neighbour(domain, own, cov), len(cell))
