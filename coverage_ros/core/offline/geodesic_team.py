"""The geodesic team step as one tessellation (:class:`coverage_ros.core.offline.lloyd_team.
GeodesicTeam`): every robot's geodesic power Voronoi cell and generalized Lloyd control
(Bhattacharya et al. 2014, Eq. 8) from one search of the whole domain, instead of one
:func:`coverage_ros.core.geodesic.cell.geodesic_cell` per robot.

1. The search gives every free cell its owner ``k``, its distance ``g`` and its parent on the
   shortest-path tree: with equal weights one multi-source search
   (:func:`coverage_ros.core.geodesic.shared_search.whole_search`, the very search the robots'
   own updates share); with power weights one search per robot, the cells kept star-shaped
   as :func:`coverage_ros.core.geodesic.cell.geodesic_cell` keeps them.
2. Every cell's tangent anchor (the point its chord at the robot aims at,
   ``cell._tangent_anchors``): the nearest ancestor-or-self on its path that is joined to the
   source (``visibility``, ``paper``) or within the look-ahead (``lookahead``). Cells in line
   of sight are their own anchors; the others take the anchor at the root of their tree of
   parent links (``scipy.sparse.csgraph.connected_components``: one pass, however deep).
3. Masses, costs and control covectors of every robot at once: sums over the owner labels
   (``np.bincount``).
4. Per robot only the 2 x 2 solve and the reachable goal (:func:`.descent.reachable_goal`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

from coverage_ros.core.geodesic.cell import LOOKAHEAD_CELLS
from coverage_ros.core.geodesic.descent import reachable_goal
from coverage_ros.core.geodesic.domain import CoverageDomain, Snap
from coverage_ros.core.geodesic.local_search import local_graph_for
from coverage_ros.core.geodesic.shared_search import whole_search
from coverage_ros.core.geodesic.tessellation import (
    Generator,
    resolve_method,
    source_row,
    star_shaped,
)

__all__ = ["TeamCells", "team_cells"]


@dataclass(frozen=True)
class TeamCells:
    """Every robot's cell and control at once (vectors in the map frame)."""

    cells: Callable[[], np.ndarray]  # maker of the (H, W) int32 labels (-1: nobody's)
    masses: np.ndarray  # (n,) sum w dA over each cell
    costs: np.ndarray  # (n,) sum (g^2 - R^2) w dA over each cell
    covectors: np.ndarray  # (n, 2) I_k, grid axes (chart units)
    controls: np.ndarray  # (n, 2) [m] steps to the virtual centroids, map frame
    goals: np.ndarray  # (n, 2) [m] virtual centroids clipped to reachable free space


@dataclass(frozen=True)
class _Forest:
    """The shortest-path trees of every cell over the domain's N nodes (row-major ids), its
    generators in an order of its own."""

    label: np.ndarray  # (N,) int64 generator owning each node, -1: nobody
    g: np.ndarray  # (N,) distance to the owner (any value where nobody's)
    parent: Callable[[np.ndarray], np.ndarray]  # nodes -> their parent node ids (-1: none)
    linked: Callable[[], np.ndarray]  # the nodes whose parent is a node (not a source)
    robot: np.ndarray  # (n,) int64 the robot of each generator


def team_cells(domain: CoverageDomain, positions: np.ndarray, weights: np.ndarray,
               method: str = "auto") -> TeamCells:
    """Every robot's :func:`~coverage_ros.core.geodesic.cell.geodesic_cell` over the whole
    domain (``whole=True``) at ``positions (n, 2)`` [m] with power ``weights (n,)`` [m], from
    one tessellation (module docstring); the same cells, sums and controls."""
    method = resolve_method(domain, method)
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    R = np.asarray(weights, dtype=np.float64).reshape(-1)
    n = len(P)
    snaps = domain.snap_many(P)
    gens = [Generator(p, r) for p, r in zip(P, R, strict=True)]
    forest = _power_forest(domain, gens, snaps, method) if np.ptp(R) > 0 \
        else _equal_forest(domain, gens, snaps, method)
    robot = forest.robot
    grids = np.array([s[2] for s in snaps]).reshape(-1, 2)
    bins = forest.label + 1  # (bin 0: nobody's nodes, dropped)
    wdA = domain.mass_element.ravel()
    with np.errstate(invalid="ignore"):  # (nobody's nodes: inf distances, into bin 0)
        gw = forest.g * wdA  # (also the control's weight of every cell)
        if np.any(R):
            f = forest.g * forest.g
            f -= np.append(0.0, (R * R)[robot])[bins]
            f *= wdA
        else:
            f = gw * forest.g
    sums = np.stack([np.bincount(bins, weights=wdA, minlength=n + 1),
                     np.bincount(bins, weights=f, minlength=n + 1)])[:, 1:]
    masses, costs = np.zeros(n), np.zeros(n)
    masses[robot], costs[robot] = sums
    covectors = np.zeros((n, 2))
    covectors[robot] = _covectors(domain, forest, bins, grids[robot], gw, method)
    metric = domain.metric_at(grids)
    res = domain.resolution
    controls, goals = np.zeros((n, 2)), np.zeros((n, 2))
    for i in range(n):
        u = np.linalg.solve(metric[i], covectors[i])
        step_chart = u / masses[i] if masses[i] > 0 else np.zeros(2)
        goal_grid = reachable_goal(domain, int(snaps[i][0][0]), grids[i], step_chart / res,
                                   covectors[i])
        goals[i] = domain.to_map(goal_grid[None])[0]
        controls[i] = domain.grid_vector_to_map(step_chart)
    to_robot = np.append(robot, -1).astype(np.int32)  # (label -1: index -1, nobody)

    def cells() -> np.ndarray:
        labels: np.ndarray = to_robot[forest.label].reshape(domain.shape)
        return labels

    return TeamCells(cells, masses, costs, covectors, controls, goals)


def _equal_forest(domain: CoverageDomain, gens: list[Generator], snaps: list[Snap],
                  method: str) -> _Forest:
    """Step 1 with equal weights: the robots' shared whole-domain search (its sources in
    its own order)."""
    local = local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1), math.inf)
    search, match = whole_search(domain, local, gens, snaps, method)
    N = local.n  # the whole-domain graph: local id = node id + 1
    label = search.label[1:N + 1]
    robot = np.empty(len(gens), dtype=np.int64)
    robot[match] = np.arange(len(gens))

    def parent(nodes: np.ndarray) -> np.ndarray:
        up: np.ndarray = search.pred[nodes + 1].astype(np.int64) - 1
        return up

    def linked() -> np.ndarray:
        pred = search.pred[1:N + 1]  # (local ids: nodes 1..N, then the sources)
        return np.flatnonzero((pred > 0) & (pred <= N))

    return _Forest(label, search.dist[1:N + 1], parent, linked, robot)


def _power_forest(domain: CoverageDomain, gens: list[Generator], snaps: list[Snap],
                  method: str) -> _Forest:
    """Step 1 with power weights: one unlimited search per robot, every node to the robot of
    the least power distance (ties: the lower index), each cell cut to the nodes whose path
    stays in it (:func:`~coverage_ros.core.geodesic.tessellation.star_shaped`)."""
    local = local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1), math.inf)
    N, n = local.n, len(gens)
    first = N + 1
    csr = local.with_sources([source_row(domain, local, s, math.inf, method) for s in snaps])
    r2 = np.array([g.weight for g in gens]) ** 2
    best = np.full(first + n, np.inf)
    label = np.full(first + n, -1, dtype=np.int64)
    own_d = np.full(first + n, np.inf)
    preds = []
    for k in range(n):  # (one at a time: n whole-domain distance rows never held at once)
        d, p = dijkstra(csr, directed=True, indices=first + k, return_predecessors=True)
        pw = d * d - r2[k]
        closer = pw < best
        best[closer], label[closer], own_d[closer] = pw[closer], k, d[closer]
        preds.append(p)
    label[0] = -1
    label[first:] = -1
    up = np.full(N, -1, dtype=np.int64)
    for k in range(n):
        mask = label == k
        keep = star_shaped(mask, preds[k], first)
        label[mask & ~keep] = -1
        mine = np.flatnonzero(keep[1:first])
        up[mine] = preds[k][mine + 1].astype(np.int64) - 1

    def parent(nodes: np.ndarray) -> np.ndarray:
        parents: np.ndarray = up[nodes]
        return parents

    def linked() -> np.ndarray:
        return np.flatnonzero((up >= 0) & (up < N))

    return _Forest(label[1:first], own_d[1:first], parent, linked, np.arange(n))


def _covectors(domain: CoverageDomain, forest: _Forest, bins: np.ndarray, grids: np.ndarray,
               gw: np.ndarray, method: str) -> np.ndarray:
    """Steps 2-3: ``(n, 2)`` every generator's I_k (grid axes, chart units; generators in the
    forest's order, at grid points ``grids``; ``gw``: every node's g w dA)."""
    H, W = domain.shape
    N = H * W
    n = len(grids)
    label = forest.label
    # the chord of every node to its owner's generator (cells, grid axes) ...
    ext = np.append(grids, [[0.0, 0.0]], axis=0)  # (nobody's nodes: index -1)
    dx, dy = np.take(ext[:, 0], label), np.take(ext[:, 1], label)  # (then in place)
    np.subtract((np.arange(W) + 0.5)[None, :], dx.reshape(H, W), out=dx.reshape(H, W))
    np.subtract((np.arange(H) + 0.5)[:, None], dy.reshape(H, W), out=dy.reshape(H, W))
    # ... aimed at its anchor instead where that is an ancestor
    deep, anchor = _deep_anchors(domain, forest, method, N)
    if len(deep):
        dx[deep] = (anchor % W + 0.5) - ext[label[deep], 0]
        dy[deep] = (anchor // W + 0.5) - ext[label[deep], 1]
    if domain.graph.wrap[1]:
        dx = (dx + 0.5 * W) % W - 0.5 * W
    if domain.graph.wrap[0]:
        dy = (dy + 0.5 * H) % H - 0.5 * H
    # (in cells, not metres: only the chord's direction counts, gw d / |d|_M)
    if domain.tensor is None and domain.zeta is None:
        mx, my = dx, dy
    else:
        M = np.append(domain.metric_at(grids), np.eye(2)[None], axis=0)[label]  # (N, 2, 2)
        mx = M[:, 0, 0] * dx + M[:, 0, 1] * dy
        my = M[:, 1, 0] * dx + M[:, 1, 1] * dy
    norm = dx * mx
    norm += dy * my
    np.sqrt(norm, out=norm)
    # no chord (a cell centre or an anchor at its generator): no direction, left out - only
    # where a generator's own cell or an anchor lies
    own = (np.floor(grids[:, 1]) * W + np.floor(grids[:, 0])).astype(np.int64)
    maybe = np.concatenate([own[(own >= 0) & (own < N)], deep])
    none = maybe[norm[maybe] <= 1e-12]
    with np.errstate(invalid="ignore", divide="ignore"):  # (nobody's: inf, into bin 0)
        coef = np.divide(gw, norm, out=norm)
    coef[none] = 0.0
    mx *= coef  # (this step's own arrays, whichever branch made them)
    my *= coef
    return np.stack([np.bincount(bins, weights=mx, minlength=n + 1),
                     np.bincount(bins, weights=my, minlength=n + 1)], axis=1)[1:]


def _deep_anchors(domain: CoverageDomain, forest: _Forest, method: str,
                  N: int) -> tuple[np.ndarray, np.ndarray]:
    """Step 2: ``(nodes, anchors)`` for the owned nodes whose tangent anchor is a node other
    than themselves - the nearest ancestor-or-self on their path that is joined to the source
    (``visibility``, ``paper``) or within the look-ahead (``lookahead``); a path without one
    keeps the node's own chord."""
    label = forest.label
    if method == "lookahead":
        candidates = np.flatnonzero((label >= 0) & (forest.g > LOOKAHEAD_CELLS
                                                    * domain.graph.max_edge_cost))
    else:  # (a node joined to the source is its own anchor)
        candidates = forest.linked()
        candidates = candidates[label[candidates] >= 0]
    up = forest.parent(candidates)
    inside = (up >= 0) & (up < N)
    inside[inside] = label[up[inside]] == label[candidates[inside]]
    if method != "lookahead":  # (joined to the source, or to another cell: its own anchor)
        candidates, up, inside = candidates[inside], up[inside], inside[inside]
    m = len(candidates)
    if m == 0:
        return candidates, candidates
    # Each candidate is linked to its parent when that is a candidate too: the links make
    # trees, each with one root (a candidate whose parent is its own anchor, or none), and
    # every candidate of a tree takes its root's anchor (-1: no anchor).
    pos = np.full(N, -1, dtype=np.int64)
    pos[candidates] = np.arange(m)
    jump = np.where(inside, pos[np.where(inside, up, 0)], -1)
    link = jump >= 0
    indptr = np.zeros(m + 1, dtype=np.int32)
    np.cumsum(link, out=indptr[1:])
    trees = csr_matrix((np.ones(int(indptr[-1]), dtype=np.int8), jump[link].astype(np.int32),
                        indptr), shape=(m, m))
    count, tree = connected_components(trees, directed=True, connection="weak")
    root_anchor = np.empty(count, dtype=np.int64)
    root_anchor[tree[~link]] = np.where(inside, up, -1)[~link]
    anchor = root_anchor[tree]
    keep = anchor >= 0
    return candidates[keep], anchor[keep]
