"""The two costs of a handover, each computed by one robot over its own cell.

A handover moves robot i out of its cell V_i into a neighbour j's cell V_j. Every other
generator stays, so after the move each grid cell may keep any owner; the geodesic power
Voronoi cells minimize H over all assignments of grid cells to generators, so the cost of any
one assignment bounds the new H from above (equal power weights). The assignment used:

* V_i and the cells of i's bordering neighbours go to those neighbours, which take a few
  Lloyd steps in that region while every other generator stays: :func:`removal_increase`
  (robot i, from its neighbours' generators, which it tessellates anyway) is the region's cost
  after minus before;
* V_j is split between j (staying where it is) and a second generator s placed by a few
  Lloyd steps inside V_j: :func:`split_offer` (robot j) is ``H_j - sum_{q in V_j}
  (min(g_j(q), g_s(q))^2 - R^2) w dA`` and the point s.

When the two regions share no node (j's cell is not among the region's movable ones: a
bordering j is held ``fixed``), ``removal_increase(i) - split_gain(j)`` bounds the change of H
from above for i at s and i's movable neighbours at the positions the removal returns. The
robots then run generalized Lloyd from i's move, not from those positions: the bound says that
a configuration that much better lies next to the one the move makes, which Lloyd's descent
reaches in the cases tested (the move is a claim backed by a configuration, not a proof about
where Lloyd ends).
Distances are the tessellation's own (:func:`~coverage_ros.core.geodesic.tessellation.
source_row` sources on the whole-domain graph), searched only as far as the cell needs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.local_search import local_graph_for
from coverage_ros.core.geodesic.tessellation import resolve_method, source_row

#: Searches reach this many longest graph edges beyond the bound they need.
SLACK_EDGES = 4.0
#: Growth of a removal search radius that left nodes of the cell unreached (then unlimited).
GROWTH = 2.0


@dataclass(frozen=True)
class SplitOffer:
    """What splitting the own cell with a second generator would save."""

    gain: float  # H_k - cost of the split (>= 0), units of H
    point: np.ndarray  # (2,) [m] map frame: where the second generator goes (a node of the cell)
    base: float  # H_k, the own cell's cost before the split


def node_points(domain: CoverageDomain, nodes: np.ndarray) -> np.ndarray:
    """``(n, 2)`` [m] map-frame centres of grid nodes ``nodes`` (row * W + col)."""
    W = domain.shape[1]
    rows, cols = np.divmod(np.asarray(nodes, dtype=np.int64), W)
    return domain.to_map(np.column_stack([cols + 0.5, rows + 0.5]))


def nearest(domain: CoverageDomain, points: np.ndarray, limit: float,
            method: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """``(H * W,)`` geodesic distance (chart units) of every node from the nearest of
    ``points (m, 2)`` [m] and that point's index, searched up to ``limit`` (inf and -1
    beyond)."""
    method = resolve_method(domain, method)
    local = local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1), math.inf)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    rows = [source_row(domain, local, domain.snap(p), limit, method) for p in pts]
    csr = local.with_sources(rows)
    n = local.n
    d, _, src = dijkstra(csr, directed=True, indices=np.arange(n + 1, n + 1 + len(rows)),
                         limit=limit, min_only=True, return_predecessors=True)
    label = np.where(src >= 0, src - (n + 1), -1)
    return d[1:n + 1], label[1:n + 1]  # whole-graph local ids are node ids + 1


@dataclass(frozen=True)
class Removal:
    """What the own generator's leaving costs at most."""

    increase: float  # rise of the region's cost, units of H (inf: not computable)
    movers: tuple[int, ...]  # indices of the neighbours that take Lloyd steps
    positions: np.ndarray  # (len(movers), 2) [m] where they stand at that cost


def removal_increase(domain: CoverageDomain, generators: np.ndarray, weight: float,
                     bordering: Sequence[int], fixed: Sequence[int], cell_radius: float,
                     steps: int, method: str = "auto") -> Removal:
    """How much H would rise at most if generator 0 of ``generators (m, 2)`` [m] (the own;
    the others: every neighbour known, all of power weight ``weight``) left its cell.

    The own cell and the cells of its ``bordering`` neighbours (indices into ``generators``)
    but ``fixed`` ones form a region U; U's nodes are assigned to the nearest of those
    neighbours and the ``fixed`` ones, the movable neighbours taking ``steps`` Lloyd steps in U
    (each to its part's node nearest the part's mass centroid), the least cost kept. Nodes
    outside U keep their owners, so with the movable neighbours at the returned positions H
    rises by at most the returned increase (inf without movable or fixed neighbours, or if a
    node of U is out of their reach)."""
    gens = np.asarray(generators, dtype=np.float64).reshape(-1, 2)
    movers = [k for k in bordering if k not in fixed]
    keep = list(fixed)
    if not movers and not keep:
        return Removal(math.inf, (), np.zeros((0, 2)))
    wdA = domain.mass_element.ravel()
    slack = SLACK_EDGES * domain.graph.max_edge_cost
    limit = 4.0 * cell_radius + slack
    own = [0, *movers]
    for _ in range(3):
        d, label = nearest(domain, gens, limit, method)
        # a cell whose nodes all lie closer than the limit by an edge is whole
        near = np.isin(label, own)
        if float(d[near].max(initial=0.0)) < limit - domain.graph.max_edge_cost:
            break
        limit *= GROWTH
    else:
        d, label = nearest(domain, gens, math.inf, method)
        near = np.isin(label, own)
    U = np.flatnonzero(near)
    before = float(((d[U] ** 2 - weight ** 2) * wdA[U]).sum())
    w, pts = wdA[U], node_points(domain, U)
    pos = gens[movers].copy()
    best, at = math.inf, pos.copy()
    for step in range(steps + 1):
        g, lab = nearest(domain, np.vstack([pos, gens[keep]]), GROWTH * limit, method)
        g, lab = g[U], lab[U]
        if not np.all(np.isfinite(g)):
            break
        value = float(((g * g - weight ** 2) * w).sum())
        if value < best:
            best, at = value, pos.copy()
        if step == steps:
            break
        for k in range(len(movers)):
            part = lab == k
            m = float(w[part].sum())
            if m > 0:
                centroid = (pts[part] * w[part, None]).sum(axis=0) / m
                pos[k] = pts[part][int(np.argmin(np.hypot(*(pts[part] - centroid).T)))]
    return Removal(best - before, tuple(movers), at)


def split_offer(domain: CoverageDomain, nodes: np.ndarray, g_own: np.ndarray, cost: float,
                weight: float, cell_radius: float, steps: int,
                method: str = "auto") -> SplitOffer | None:
    """The best split of the own cell ``nodes`` (distances ``g_own`` from the own generator,
    cost ``cost``) with a second generator of the own power weight: started at the node
    farthest from the own generator, moved ``steps`` times to the mass centroid of its part
    (the part's node nearest to it); the least cost seen. None for a cell of fewer than two
    nodes."""
    nodes = np.asarray(nodes, dtype=np.int64)
    if len(nodes) < 2:
        return None
    wdA = domain.mass_element.ravel()[nodes]
    pts = node_points(domain, nodes)
    own = g_own * g_own - weight ** 2
    limit = 2.0 * cell_radius + SLACK_EDGES * domain.graph.max_edge_cost
    s = pts[int(np.argmax(g_own))]
    best_cost, best_point = cost, s
    for _ in range(max(1, steps)):
        gs = nearest(domain, s[None], limit, method)[0][nodes]
        theirs = np.where(np.isfinite(gs), gs * gs - weight ** 2, np.inf)
        mine = theirs < own
        split = float(np.where(mine, theirs, own).dot(wdA))
        if split < best_cost:
            best_cost, best_point = split, s
        m = float(wdA[mine].sum())
        if m <= 0:
            break
        centroid = (pts[mine] * wdA[mine, None]).sum(axis=0) / m
        part = pts[mine]
        nxt = part[int(np.argmin(np.hypot(*(part - centroid).T)))]
        if np.allclose(nxt, s):
            break
        s = nxt
    return SplitOffer(gain=max(cost - best_cost, 0.0), point=best_point.copy(), base=cost)
