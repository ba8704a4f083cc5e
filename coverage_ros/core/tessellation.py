"""Geodesic power Voronoi tessellation and the generalized Lloyd control (seed 000, sec. 3-4).

Cell of generator k (Eq. 2 with f_k(x) = x^2 - R_k^2)::

    V_k = { q : g_k(q)^2 - R_k^2 <= g_j(q)^2 - R_j^2 for all j }

with g_k the shortest-path distance on the domain's metric graph from generator k's position
(a virtual source joined to the cells around it, see :func:`resolve_method`). With unequal power
weights, a geodesic power cell need not be star-shaped: behind obstacles it can reappear beyond
a band where a neighbour wins. Such islands are what the paper's wavefront search (labels spread
only through a generator's own cells) never produces and what no local search can be sure to
find, so a cell keeps only the q whose shortest path from its generator stays in the cell;
islands belong to nobody (:attr:`Tessellation.unassigned`). With equal weights cells are always
star-shaped and nothing is dropped. The control covector of Eq. 8 is integrated
over the own cell::

    I_k = sum_{q in V_k} g_k(q) * M z / sqrt(z' M z) * w(q) dA(q),    M = eta(p_k)

where z is the tangent at p_k of the geodesic to q (see :mod:`coverage_ros.core.tangents`).
I_k is minus half the gradient of the coverage cost H; its dual ``u = M^-1 I_k`` divided by the
cell mass is the step to the cell's *virtual centroid*, which is the ordinary centroid in the
convex Euclidean case - the classic Lloyd step.

:func:`geodesic_cell` is the decentralized update: from its own position and its neighbours'
positions only, a robot computes its own cell. It searches a window around itself pruned to
its own ball and the "lenses" where a neighbour could possibly be closer (exact Euclidean lower
bounds of the metric), with scipy's compiled Dijkstra limited to a distance L; if the cell
touches the search frontier, L grows. The work is proportional to the own cell's area, not to
the map or the team. :func:`tessellate` is the centralized tessellation on the whole graph.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.domain import CoverageDomain, tie_bias
from coverage_ros.core.local_search import LocalGraph, SearchCache, local_graph_for
from coverage_ros.core.tangents import ancestor_table, first_ancestor_where

__all__ = ["CellResult", "Generator", "SearchCache", "Tessellation", "geodesic_cell",
           "tessellate"]

#: Growth factor of the search radius when a cell was not complete.
GROWTH = 1.6
#: Slack on a warm-start search radius: the last cell's radius plus this many longest edges
#: (robots move a few centimetres between updates; a cell that outgrew it costs a second pass).
WARM_SLACK_EDGES = 2.0
#: Cold start: the search radius is COLD_FACTOR times the distance to the COLD_NEIGHBOURS-th
#: nearest neighbour.
COLD_NEIGHBOURS = 4
COLD_FACTOR = 0.6
#: [cells] granularity of warm-start search radii.
RADIUS_STEP_CELLS = 2.0
#: A straight step to the virtual centroid that is blocked before this fraction of its length
#: is replaced by a walk along the gradient through the free space, of at most WALK_CELLS.
BLOCKED_FRACTION = 0.25
WALK_CELLS = 20.0
#: Walk steps must make progress along the gradient: cos of at most ~75 degrees off it.
WALK_MIN_ALIGNMENT = 0.25
#: [cells] look-ahead of tangent chords on non-Euclidean metrics.
LOOKAHEAD_CELLS = 3.0


@dataclass(frozen=True)
class Generator:
    """A robot as the tessellation sees it: position (map frame) and power weight R [m]."""

    position: np.ndarray  # (2,) [m]
    weight: float = 0.0  # R_k: f_k(x) = x^2 - R_k^2

    @staticmethod
    def of(x: float, y: float, weight: float = 0.0) -> Generator:
        return Generator(np.array([x, y], dtype=np.float64), float(weight))


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
    passes: int  # searches run (1 when the first radius sufficed)

    @property
    def centroid_distance(self) -> float:
        return float(np.hypot(*self.control))


@dataclass(frozen=True)
class Tessellation:
    """Centralized tessellation: labels and distances for every cell of the grid."""

    labels: np.ndarray  # (H, W) int64 generator index, -1 where unreachable/blocked
    distances: np.ndarray  # (H, W) g to the own generator (inf where unlabeled)
    masses: np.ndarray  # (n,) sum w dA per cell
    costs: np.ndarray  # (n,) sum (g^2 - R^2) w dA per cell
    unassigned: float = 0.0  # mass of power-cell islands no generator keeps (see module doc)

    @property
    def cost(self) -> float:
        return float(self.costs.sum())


# ---------------------------------------------------------------------------- decentralized
METHODS = ("auto", "visibility", "paper", "lookahead")


def geodesic_cell(domain: CoverageDomain, own: Generator, others: Sequence[Generator],
                  cache: SearchCache | None = None, method: str = "auto") -> CellResult:
    """The decentralized update of one robot (see module docstring).

    ``others`` are the neighbours this robot knows about (any number; far ones are ignored).
    ``cache`` (one per robot) keeps the search graph and the last cell radius between updates,
    which makes successive updates of a slowly moving robot much cheaper.
    ``method`` picks the sources and tangents (see :func:`resolve_method`).
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
    if len(others) == 0:
        L = math.inf
    elif hint is not None and hint > 0:
        # Rounded up to whole steps so the small changes of the cell radius between updates
        # keep the search region (and its cache) the same.
        step = RADIUS_STEP_CELLS * res
        L = math.ceil((hint + WARM_SLACK_EDGES * max_edge) / step) * step
    else:
        # A cell rarely reaches past half the distance to the nearer neighbours around it;
        # if it does, the search grows.
        dists = np.sort(lam * res * np.hypot(*(centers[1:] - centers[0]).T))
        near = dists[min(len(dists), COLD_NEIGHBOURS) - 1]
        L = max(COLD_FACTOR * near, 4.0 * max_edge)
    passes = 0
    while True:
        passes += 1
        # Competitor j can claim q only where g_j(q) < L_j = sqrt(L^2 - R_i^2 + R_j^2).
        radii = np.sqrt(np.maximum(L * L - weights[0] ** 2 + weights ** 2, 0.0))
        radii[0] = L
        if math.isfinite(L):
            dist_c = lam * res * np.hypot(*(centers - centers[0]).T)
            relevant = np.flatnonzero(dist_c <= L + radii)
            relevant = relevant[relevant > 0]
        else:
            relevant = np.arange(1, len(gens))
        idx = np.concatenate([[0], relevant]).astype(np.int64)
        local = local_graph_for(domain, cache, centers[idx], radii[idx], L)
        csr = local.with_sources([source_row(domain, local, snaps[k], radii[k], method)
                                  for k in idx])
        found = _search(local, csr, weights[idx], radii[idx], L, power)
        if found is not None:
            break
        if local.covers_all and math.isfinite(L):
            L = math.inf  # the region is everything already: drop the limit instead
            continue
        if not math.isfinite(L):  # unreachable: the unlimited search has no frontier
            raise AssertionError("unlimited search reported an incomplete cell")
        L *= GROWTH
    own_local, g, pred, touching = found
    result = _finish(domain, local, int(snaps[0][0][0]), centers[0], weights[0], own_local, g,
                     pred,
                     [int(idx[t]) - 1 for t in touching], L, passes, method)
    if cache is not None:
        cache.cell_radius = result.cell_radius
    return result


def resolve_method(domain: CoverageDomain, method: str) -> str:
    """``visibility``: sources joined to every cell in line of sight at its straight-line
    distance, tangents toward the first vertex after the source (the last visible point of the
    path) - exact Euclidean geodesics up to the first corner; the default on maps.
    ``paper``: sources joined to the cells around them and first-edge tangents - seed 000's
    pseudo-code. ``lookahead``: like ``paper`` but with look-ahead tangent chords; the default
    on curved charts, where straight lines are not geodesics."""
    if method not in METHODS:
        raise ValueError(f"method: unknown {method!r}, expected one of {METHODS}")
    if method == "auto":
        return "visibility" if domain.sees_straight else "lookahead"
    if method == "visibility" and not domain.sees_straight:
        raise ValueError("method: 'visibility' needs a Euclidean, non-wrapping domain")
    return method


def source_row(domain: CoverageDomain, local: LocalGraph, snap: tuple, radius: float,
                method: str) -> tuple[np.ndarray, np.ndarray]:
    """Local ids and costs of one virtual source's edges (see :func:`resolve_method`)."""
    nodes, costs, g = snap
    lid = local.local_of(nodes)
    keep = lid > 0
    if method != "visibility":
        return lid[keep], costs[keep]
    r_cells = radius / domain.resolution if math.isfinite(radius) else math.inf
    band = local.rows_slice(g[1] - r_cells, g[1] + r_cells) if math.isfinite(r_cells) \
        else slice(0, local.n)
    c = local.centers[band]
    d2 = (c[:, 0] - g[0]) ** 2 + (c[:, 1] - g[1]) ** 2
    near = np.flatnonzero((d2 <= r_cells * r_cells) & local.seedable[band])
    reach = math.sqrt(float(d2[near].max())) if len(near) else 0.0
    vis = near[domain.visible_mask(g, c[near], reach)]
    return (np.concatenate([lid[keep], vis + band.start + 1]),
            np.concatenate([costs[keep], np.sqrt(d2[vis]) * domain.resolution + tie_bias(g)]))


def _search(local: LocalGraph, csr: csr_matrix, weights: np.ndarray, radii: np.ndarray,
            L: float, power: bool, force: bool = False):
    """Run the limited Dijkstra; None if the own cell reaches the search frontier.

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
        all_d = np.empty((len(weights), first + len(weights)))
        pred = None
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


def star_shaped(mask: np.ndarray, pred: np.ndarray, first_source: int) -> np.ndarray:
    """``(N,) bool``: nodes of ``mask`` whose every ancestor in the shortest-path tree ``pred``
    (predecessors; sources are the ids >= ``first_source``; -9999 for none) is in ``mask``."""
    n = len(mask)
    ok = mask.copy()
    up = np.where(pred >= 0, pred, np.arange(n))
    is_root = (np.arange(n) >= first_source) | (pred < 0)
    ok[is_root] = True
    up[is_root] = np.flatnonzero(is_root)
    while True:
        nxt = ok & ok[up]
        up2 = up[up]
        if np.array_equal(nxt, ok) and np.array_equal(up2, up):
            break
        ok, up = nxt, up2
    return ok & mask


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
    goal_grid = _clip_reachable(domain, own_grid, own_grid + step_grid)
    wanted = float(np.hypot(*step_grid))
    if wanted > 1.0 and float(np.hypot(*(goal_grid - own_grid))) < BLOCKED_FRACTION * wanted:
        # The straight step is blocked almost at once (a robot in a doorway heading for a
        # centroid beyond the door frame): follow the gradient through the free space instead.
        walk = _descent_walk(domain, base_node, covector, min(wanted, WALK_CELLS))
        if float(np.hypot(*(walk - own_grid))) > float(np.hypot(*(goal_grid - own_grid))):
            goal_grid = walk
    goal = domain.to_map(goal_grid[None])[0]
    control = domain.grid_vector_to_map(step_chart)
    nxt = _next_vertex(domain, base_node, covector)
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
    return pts[anchor]


def _clip_reachable(domain: CoverageDomain, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """The farthest point toward ``goal`` on the straight segment that stays in free cells."""
    if any(domain.graph.wrap):
        return goal
    d = goal - start
    length = float(np.hypot(*d))
    if length < 1e-9:
        return goal
    t = np.linspace(0.0, 1.0, int(math.ceil(length * 4.0)) + 2)
    pts = start + t[:, None] * d
    _, _, ok = domain.free_at_grid(pts)
    if ok.all():
        return goal
    if not ok[0]:
        return start
    last = int(np.argmin(ok)) - 1
    return pts[max(last, 0)]


def _descent_walk(domain: CoverageDomain, base: int, covector: np.ndarray,
                  length_cells: float) -> np.ndarray:
    """Grid point reached by walking from vertex ``base`` along graph edges, each step to the
    neighbour best aligned with the covector (seed 000's next-vertex rule, repeated), for about
    ``length_cells``; stops where no neighbour makes progress along it."""
    graph = domain.graph
    W = graph.shape[1]
    direction = covector / max(float(np.hypot(*covector)), 1e-300)
    dirs = graph.offsets[:, ::-1].astype(np.float64)  # (x, y) per offset, cells
    lengths = np.hypot(dirs[:, 0], dirs[:, 1])
    align = (dirs @ direction) / lengths
    node, travelled, seen = base, 0.0, {base}
    while travelled < length_cells:
        r, c = divmod(node, W)
        ok = np.isfinite(graph.cost[r, c]) & (align > WALK_MIN_ALIGNMENT)
        if not ok.any():
            break
        k = int(np.argmax(np.where(ok, align, -np.inf)))
        nxt = int(graph.neighbour_index(k)[r, c])
        if nxt in seen:
            break
        seen.add(nxt)
        node = nxt
        travelled += float(lengths[k])
    return domain.node_centers(np.array([node]))[0]


def _next_vertex(domain: CoverageDomain, base: int, covector: np.ndarray) -> np.ndarray:
    """The graph neighbour of vertex ``base`` best aligned with the covector (paper, l. 32)."""
    graph = domain.graph
    W = graph.shape[1]
    r, c = divmod(base, W)
    ok = np.isfinite(graph.cost[r, c])
    best = base
    if ok.any():
        v = graph.offsets[ok][:, ::-1].astype(np.float64) * domain.resolution  # (x, y) chart
        score = v @ covector
        k = int(np.argmax(score))
        if score[k] > 0:
            best = int(graph.neighbour_index(int(np.flatnonzero(ok)[k]))[r, c])
    return domain.to_map(domain.node_centers(np.array([best])))[0]


# ---------------------------------------------------------------------------- centralized
def _full_with_sources(domain: CoverageDomain, gens: Sequence[Generator],
                       method: str = "auto") -> tuple[csr_matrix, int]:
    method = resolve_method(domain, method)
    base = domain.graph.csr
    N = base.shape[0]
    indices, data, counts = [base.indices], [base.data], []
    free_nodes = np.flatnonzero(domain.free.ravel())
    centers = domain.node_centers(free_nodes)
    for gen in gens:
        if method == "visibility":
            nodes, costs, _ = domain.seeds(gen.position, free_nodes, centers, math.inf)
        else:
            nodes, costs, _ = domain.snap(gen.position)
        indices.append(nodes.astype(np.int32))
        data.append(np.maximum(costs, 1e-12))
        counts.append(len(nodes))
    indptr = np.concatenate([base.indptr.astype(np.int64),
                             base.indptr[-1] + np.cumsum(counts)]).astype(np.int32)
    total = N + len(gens)
    return csr_matrix((np.concatenate(data), np.concatenate(indices), indptr),
                      shape=(total, total)), N


def tessellate(domain: CoverageDomain, gens: Sequence[Generator],
               method: str = "auto") -> Tessellation:
    """Centralized geodesic power Voronoi tessellation of the whole domain."""
    csr, N = _full_with_sources(domain, gens, method)
    sources = np.arange(N, N + len(gens))
    weights = np.array([g.weight for g in gens], dtype=np.float64)
    if np.ptp(weights) == 0:
        dist, _, src = dijkstra(csr, directed=True, indices=sources, min_only=True,
                                return_predecessors=True)
        labels = np.where(src[:N] >= 0, src[:N] - N, -1)
        g = dist[:N]
    else:
        all_d, preds = dijkstra(csr, directed=True, indices=sources, return_predecessors=True)
        pw = all_d[:, :N] ** 2 - (weights ** 2)[:, None]
        labels = np.argmin(pw, axis=0)
        labels[~np.isfinite(pw.min(axis=0))] = -1
        for k in range(len(gens)):  # drop the islands (see module docstring)
            mask = np.append(labels == k, np.zeros(len(gens), bool))
            keep = star_shaped(mask, preds[k], N)[:N]
            labels[(labels == k) & ~keep] = -2
        g = np.take_along_axis(all_d[:, :N], np.maximum(labels, 0)[None], axis=0)[0]
    unassigned = float(domain.mass_element.ravel()[labels == -2].sum())
    labels = np.where(domain.free.ravel() & (labels >= 0), labels, -1)
    g = np.where(labels >= 0, g, np.inf)
    wdA = domain.mass_element.ravel()
    n = len(gens)
    lab = np.maximum(labels, 0)
    valid = labels >= 0
    masses = np.bincount(lab[valid], weights=wdA[valid], minlength=n)
    f = g[valid] ** 2 - weights[lab[valid]] ** 2
    costs = np.bincount(lab[valid], weights=f * wdA[valid], minlength=n)
    return Tessellation(labels.reshape(domain.shape), g.reshape(domain.shape), masses, costs,
                        unassigned)

