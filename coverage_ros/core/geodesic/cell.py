"""One robot's decentralized update: its own geodesic power Voronoi cell and the generalized
Lloyd control (Bhattacharya et al. 2014, Sec. 4, Eq. 8).

From its own position and its neighbours' positions only, a robot computes its own cell. It
searches a window around itself pruned to its own ball and the "lenses" where a neighbour could
possibly be closer (exact Euclidean lower bounds of the metric, :mod:`.local_search`), with
scipy's compiled Dijkstra limited to a distance L; if the cell touches the search frontier, L
grows. The work is proportional to the own cell's area, not to the map or the team. The cell is
the same as the centralized tessellation's (:func:`.tessellation.tessellate`; tests check).

The control covector of Eq. 8 is integrated over the own cell::

    I_k = sum_{q in V_k} g_k(q) * M z / sqrt(z' M z) * w(q) dA(q),    M = eta(p_k)

where z is the tangent at p_k of the geodesic to q (see :mod:`.tangents`). I_k is minus half the
gradient of the coverage cost H; its dual ``u = M^-1 I_k`` divided by the cell mass is the step
to the cell's *virtual centroid*, which is the ordinary centroid in the convex Euclidean case -
the classic Lloyd step (:mod:`.descent` turns it into a reachable goal).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.descent import next_vertex, reachable_goal
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.local_search import (
    SIGHT_WHOLE_SHARE,
    WHOLE_SHARE,
    LocalGraph,
    SearchCache,
    local_graph_for,
)
from coverage_ros.core.geodesic.power_rows import whole_power_rows
from coverage_ros.core.geodesic.shared_search import held_search, shared_search
from coverage_ros.core.geodesic.tangents import ancestor_table, first_ancestor_where
from coverage_ros.core.geodesic.tessellation import (
    Generator,
    resolve_method,
    source_row,
    star_shaped,
)

__all__ = ["CellResult", "SearchCache", "geodesic_cell"]

#: Growth factor of the search radius when a cell was not complete.
GROWTH = 1.6
#: Slack on a warm-start search radius: the last cell's radius plus this many longest edges
#: (robots move a few centimetres between updates; a cell that outgrew it costs a second pass).
WARM_SLACK_EDGES = 2.0
#: [cells] Cold start: the own power cell's extent is measured in straight lines over the free
#: cells of every COLD_STRIDE-th row and column (see :func:`cold_radius`).
COLD_STRIDE = 4
#: [cells] granularity of warm-start search radii.
RADIUS_STEP_CELLS = 2.0
#: [cells] look-ahead of tangent chords on non-Euclidean metrics.
LOOKAHEAD_CELLS = 3.0


@dataclass(frozen=True)
class CellResult:
    """One robot's cell and control (vectors in the map frame)."""

    nodes: np.ndarray  # (n,) int64 node ids of the cell (row * W + col)
    distances: np.ndarray  # (n,) g(q), chart units
    mass: float  # sum w dA over the cell
    cost: float  # H_k = sum (g^2 - R_k^2) w dA over the cell
    covector: np.ndarray  # (2,) I_k, grid axes (chart)
    control: np.ndarray  # (2,) [m] step to the virtual centroid, map frame
    goal: np.ndarray  # (2,) [m] virtual centroid, clipped to reachable free space
    next_vertex: np.ndarray  # (2,) [m] neighbouring vertex best aligned with I_k (paper l.32)
    neighbours: tuple[int, ...]  # indices (into `others`) of generators sharing a boundary
    search_radius: float  # the limit L of the final pass
    cell_radius: float  # max g over the cell (hint for the next update)
    searched_nodes: int  # nodes in the pruned search graph of the final pass
    passes: int  # searches run (1 when the first radius sufficed; 0: a sibling's search reused)

def geodesic_cell(domain: CoverageDomain, own: Generator, others: Sequence[Generator],
                  cache: SearchCache | None = None, method: str = "auto",
                  whole: bool = False, reuse: float = 0.0) -> CellResult:
    """The decentralized update of one robot (see module docstring).

    ``others`` are the neighbours this robot knows about (any number; far ones are ignored).
    ``cache`` (one per robot) keeps the search graph and the last cell radius between updates,
    which makes successive updates of a slowly moving robot much cheaper.
    ``method`` picks the sources and tangents (see :func:`resolve_method`). ``whole``: search
    the whole domain at once - for domains that change every update (exploration), whose weak
    metric lower bound would make the pruned search regions nearly the whole map anyway.
    ``reuse`` [m]: take the cell from the domain's last whole-map search (equal weights), if
    another robot made it since this one's last update (``cache``), when each generator is
    within this distance of one of that search's, one to one - the exact cell of a generator
    set that close, with the own control from the own generator there (robots of one process
    share their searches so; :mod:`.shared_search`). 0: only the very same set.
    """
    method = resolve_method(domain, method)
    res = domain.resolution
    lam = domain.metric_lower_bound
    others = [o for o in others if np.all(np.isfinite(o.position))]
    gens = [own, *others]
    snaps = domain.snap_many(np.array([g.position for g in gens]))
    centers = np.array([s[2] for s in snaps])  # grid coordinates
    weights = np.array([g.weight for g in gens], dtype=np.float64)
    power = bool(np.ptp(weights) > 0)
    max_edge = domain.graph.max_edge_cost
    hint = cache.cell_radius if cache is not None else None
    cold = hint is None or not hint > 0
    if len(others) == 0 or whole:
        L = math.inf
    elif hint is not None and not cold:
        # Rounded up to whole steps so the small changes of the cell radius between updates
        # keep the search region (and its cache) the same.
        step = RADIUS_STEP_CELLS * res
        L = math.ceil((hint + WARM_SLACK_EDGES * max_edge) / step) * step
    else:
        L = max(cold_radius(domain, centers, weights), 4.0 * max_edge)
    # (a whole-map search that settles what is in line of sight first pays off sooner)
    share = SIGHT_WHOLE_SHARE if method == "visibility" and not power else WHOLE_SHARE
    passes = 0
    last = cache.whole_search if cache is not None else None
    held = (held_search(domain, gens, method, reuse, last)
            if reuse > 0 and not power and not whole and others else None)
    while held is None:
        passes += 1
        # Competitor j can claim q only where g_j(q) < L_j = sqrt(L^2 - R_i^2 + R_j^2).
        radii = np.sqrt(np.maximum(L * L - weights[0] ** 2 + weights ** 2, 0.0))
        radii[0] = L
        if math.isfinite(L):
            # Chart distance to the shortest image: on a chart that wraps (torus, sphere) a
            # neighbour near across the seam is far in the unwrapped chart, and leaving it out
            # handed part of its cell to this robot (Fig. 16's torus: H rose).
            d = domain.chart_displacement(np.repeat(centers[:1], len(centers), axis=0),
                                          centers)
            dist_c = lam * np.hypot(d[:, 0], d[:, 1])
            relevant = np.flatnonzero(dist_c <= L + radii)
            relevant = relevant[relevant > 0]
        else:
            relevant = np.arange(1, len(gens))
        idx = np.concatenate([[0], relevant]).astype(np.int64)
        local = local_graph_for(domain, cache, centers[idx], radii[idx], L, share)
        # The whole map, settling what is in line of sight first, when the region is a large
        # share of it (a team still bunched up leaves a few robots half the map each; the
        # share: local_search.SIGHT_WHOLE_SHARE / WHOLE_SHARE) or a first pass
        # was too short (a small cell may border the cell of a robot far away along paths,
        # whose distance certifies the border: several growth passes in a bunched team). The
        # other sources, too, search the whole map without a limit when the region is most of
        # it: a limited pass there settles nearly as many vertices, and a cell reaching beyond
        # the radius (round an obstacle) would search the map again (Fig. 13: two passes of
        # 37,400). On a chart that wraps the region is always the whole graph; there only a
        # cold update (whose radius is unlimited anyway) does.
        wraps = any(domain.graph.wrap)
        if not power and (whole or (local.covers_all and (cold or not wraps))
                          or (method == "visibility" and passes > 1)):
            if not whole:
                local = local_graph_for(domain, None, centers[:1], radii[:1], math.inf)
                idx = np.arange(len(gens))  # every generator takes part (touching: into gens)
            held = shared_search(domain, local, gens, snaps, method, reuse, last)
            break
        csr = local.with_sources([source_row(domain, local, snaps[k], radii[k], method)
                                  for k in idx])
        rows = whole_power_rows(domain, csr, [snaps[k] for k in idx], method) \
            if power and not math.isfinite(L) and local.covers_all else None
        found = _search(local, csr, weights[idx], radii[idx], L, power, rows=rows)
        if found is not None:
            break
        if local.covers_all and math.isfinite(L):
            L = math.inf  # the region is everything already: drop the limit instead
            continue
        if not math.isfinite(L):  # unreachable: the unlimited search has no frontier
            raise AssertionError("unlimited search reported an incomplete cell")
        L *= GROWTH
    if held is not None:  # the cell of the own generator in a whole-map search
        local, (own_local, g, pred, touching), base, grid = held
        result = _finish(domain, local, base, grid, weights[0], own_local, g, pred,
                         [int(t) - 1 for t in touching], math.inf, passes, method)
    else:
        assert found is not None  # (the loop ends with a cell or a whole-map search)
        own_local, g, pred, touching = found
        result = _finish(domain, local, int(snaps[0][0][0]), centers[0], weights[0],
                         own_local, g, pred, [int(idx[t]) - 1 for t in touching], L, passes,
                         method)
    if cache is not None:
        cache.cell_radius = result.cell_radius
        cache.whole_search = domain._cache.get("shared_search")
    return result


def cold_radius(domain: CoverageDomain, centers: np.ndarray, weights: np.ndarray) -> float:
    """Search radius (chart units) for an update without a previous one: how far the own power
    cell reaches in straight lines over the free cells (sampled every COLD_STRIDE cells), times
    the metric's lower bound, plus the sampling gap. Geodesic distances are never shorter, so
    this is the cell's extent where it lies in plain sight of its robot; a cell that reaches
    further (round an obstacle) makes the search grow. A team still bunched up has a few very
    large cells, which a radius from the nearest neighbours found only after many growth
    passes."""
    if any(domain.graph.wrap) or len(centers) < 2:
        return math.inf  # no straight lines across a chart's seam; a lone robot: everything
    key = ("cold_samples", COLD_STRIDE)
    pts = domain._cache.get(key)
    if pts is None:
        rows, cols = np.nonzero(domain.free[::COLD_STRIDE, ::COLD_STRIDE])
        pts = domain._cache[key] = np.stack([cols * COLD_STRIDE + 0.5,
                                             rows * COLD_STRIDE + 0.5], axis=-1)
    if len(pts) == 0:
        return 0.0
    scale = (domain.metric_lower_bound * domain.resolution) ** 2
    own = scale * ((pts[:, 0] - centers[0, 0]) ** 2 + (pts[:, 1] - centers[0, 1]) ** 2)
    best = np.full(len(pts), np.inf)
    for c, w in zip(centers[1:], weights[1:], strict=True):  # one pass each: O(samples) memory
        np.minimum(best, scale * ((pts[:, 0] - c[0]) ** 2 + (pts[:, 1] - c[1]) ** 2) - w * w,
                   out=best)
    mine = own - weights[0] ** 2 <= best
    reach = math.sqrt(float(own[mine].max())) if mine.any() else 0.0
    return reach + math.sqrt(2.0 * scale) * COLD_STRIDE


def _search(local: LocalGraph, csr: csr_matrix, weights: np.ndarray, radii: np.ndarray,
            L: float, power: bool, force: bool = False,
            rows: list[tuple[np.ndarray, np.ndarray]] | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Run the limited Dijkstra; None if the own cell reaches the search frontier. ``rows``:
    with power weights, every source's search already made (distances, predecessors).

    Returns ``(own, g, pred, touching)``: local ids (1..n) of the own cell, their distances, the
    own shortest-path tree's predecessors (local ids) and the generators bordering the cell.
    """
    n = local.n
    first = n + 1
    sources = np.arange(first, first + len(weights))
    limit = L if math.isfinite(L) else np.inf
    if not power:
        dist, pred, src = dijkstra(csr, directed=True, indices=sources, min_only=True,
                                   return_predecessors=True, limit=limit)
        label = src - first
        label[src < 0] = -1
        own_dist = dist
    else:
        if rows is not None:
            all_d, pred = np.stack([d for d, _ in rows]), rows[0][1]
        else:
            all_d = np.empty((len(weights), first + len(weights)))
            for k in range(len(weights)):
                lim = radii[k] if math.isfinite(L) else np.inf
                if k == 0:
                    all_d[0], pred = dijkstra(csr, directed=True, indices=sources[0],
                                              return_predecessors=True, limit=lim)
                else:
                    all_d[k] = dijkstra(csr, directed=True, indices=sources[k], limit=lim)
        pw = all_d ** 2 - (weights ** 2)[:, None]
        label = np.argmin(pw, axis=0)
        label[~np.isfinite(pw.min(axis=0))] = -1
        own_dist = all_d[0]
        label[0] = -1
        # Keep only the star-shaped part of the own power cell (see module docstring).
        drop = (label == 0) & ~star_shaped(label == 0, pred, first)
        label[drop] = -2  # nobody's, but known: not a reason to grow the search
    label[0] = -1  # the sink belongs to nobody
    own = np.flatnonzero(label[1:first] == 0) + 1
    nb = local.nb[own - 1]
    edge = local.edge[own - 1]
    nb_label = label[nb]
    # A neighbouring cell outside the search region (the sink), or reached by nobody within the
    # limits, could still belong to the own cell: then the search must grow.
    frontier = edge & (nb_label == -1)
    if frontier.any() and not force:
        return None
    touching = np.unique(nb_label[edge & (nb_label > 0)])
    return own, own_dist[own], pred, touching


def _finish(domain: CoverageDomain, local: LocalGraph, base_node: int, own_grid: np.ndarray,
            own_weight: float, own_local: np.ndarray, g: np.ndarray, pred: np.ndarray,
            touching: list[int], L: float, passes: int, method: str) -> CellResult:
    nodes = local.global_nodes[own_local - 1]
    n_own = len(own_local)
    wdA = domain.mass_element.ravel()[nodes]
    mass = float(wdA.sum())
    cost = float(((g * g - own_weight ** 2) * wdA).sum())
    pts = domain.node_centers(nodes)
    covector = np.zeros(2)
    if n_own:
        anchors = _tangent_anchors(domain, own_local, g, pred, pts, method)
        z = domain.chart_displacement(own_grid[None], anchors)
        M = domain.metric_at(own_grid[None])[0]
        Mz = z @ M.T
        norm = np.sqrt(np.einsum("ni,ni->n", z, Mz))
        ok = norm > 1e-12
        covector = ((g[ok] * wdA[ok] / norm[ok])[:, None] * Mz[ok]).sum(axis=0)
    u = np.linalg.solve(domain.metric_at(own_grid[None])[0], covector)
    step_chart = u / mass if mass > 0 else np.zeros(2)
    step_grid = step_chart / domain.resolution
    goal_grid = reachable_goal(domain, base_node, own_grid, step_grid, covector)
    goal = domain.to_map(goal_grid[None])[0]
    control = domain.grid_vector_to_map(step_chart)
    nxt = next_vertex(domain, base_node, covector)
    return CellResult(
        nodes=nodes, distances=g, mass=mass, cost=cost, covector=covector, control=control,
        goal=goal, next_vertex=nxt, neighbours=tuple(sorted(set(touching))),
        search_radius=L, cell_radius=float(g.max()) if n_own else 0.0,
        searched_nodes=local.n, passes=passes)


def _tangent_anchors(domain: CoverageDomain, own_local: np.ndarray, g: np.ndarray,
                     pred: np.ndarray, pts: np.ndarray, method: str) -> np.ndarray:
    """Grid coordinates of the point each cell's tangent chord aims at: the first vertex
    after the source on its shortest path (``visibility``, ``paper``), or the last vertex
    within the look-ahead distance (``lookahead``)."""
    n_own = len(own_local)
    pos = np.full(len(pred), -1, dtype=np.int64)
    pos[own_local] = np.arange(n_own)
    parent = pos[np.maximum(pred[own_local], 0)]
    parent[(pred[own_local] < 0) | (parent < 0)] = n_own  # virtual source (root)
    if method == "lookahead":
        flag = g <= LOOKAHEAD_CELLS * domain.graph.max_edge_cost
    else:
        flag = parent == n_own
    if flag.all():
        return pts  # every cell is joined to the source directly: the chord is the tangent
    up = ancestor_table(np.append(parent, n_own))
    anchor = first_ancestor_where(up, np.arange(n_own), np.append(flag, True))
    anchor = np.where(anchor == n_own, np.arange(n_own), anchor)
    tangents: np.ndarray = pts[anchor]
    return tangents
