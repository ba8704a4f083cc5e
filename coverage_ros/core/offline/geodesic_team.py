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
   of sight are their own anchors; the others are resolved together by pointer doubling over
   the parent links (``log2`` of the deepest path passes).
3. Masses, costs and control covectors of every robot at once: sums over the owner labels
   (``np.bincount``).
4. Per robot only the 2 x 2 solve and the reachable goal (:func:`.descent.reachable_goal`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import dijkstra

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

    labels: np.ndarray  # (H, W) int32 the robot whose cell holds each grid cell, -1 nobody's
    masses: np.ndarray  # (n,) sum w dA over each cell
    costs: np.ndarray  # (n,) sum (g^2 - R^2) w dA over each cell
    covectors: np.ndarray  # (n, 2) I_k, grid axes (chart units)
    controls: np.ndarray  # (n, 2) [m] steps to the virtual centroids, map frame
    goals: np.ndarray  # (n, 2) [m] virtual centroids clipped to reachable free space


@dataclass(frozen=True)
class _Forest:
    """The shortest-path trees of every cell over the domain's nodes (row-major ids)."""

    nodes: np.ndarray  # (m,) int64 the nodes owned by some robot
    owner: np.ndarray  # (m,) int64 their robot
    g: np.ndarray  # (m,) distance to the owner
    parent: np.ndarray  # (m,) int64 parent node in the owner's tree, -1: joined to the source


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
    nodes, k, g = forest.nodes, forest.owner, forest.g
    wdA = domain.mass_element.ravel()[nodes]
    masses = np.bincount(k, weights=wdA, minlength=n)
    costs = np.bincount(k, weights=(g * g - (R * R)[k]) * wdA, minlength=n)
    grids = np.array([s[2] for s in snaps]).reshape(-1, 2)
    covectors = _covectors(domain, forest, grids, wdA, method, n)
    labels = np.full(domain.shape, -1, dtype=np.int32)
    labels.ravel()[nodes] = k
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
    return TeamCells(labels, masses, costs, covectors, controls, goals)


def _equal_forest(domain: CoverageDomain, gens: list[Generator], snaps: list[Snap],
                  method: str) -> _Forest:
    """Step 1 with equal weights: the robots' shared whole-domain search."""
    local = local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1), math.inf)
    search, match = whole_search(domain, local, gens, snaps, method)
    N = local.n  # the whole-domain graph: local id = node id + 1
    label = search.label[1:N + 1]
    nodes = np.flatnonzero(label >= 0)
    robot_of = np.empty(len(gens), dtype=np.int64)
    robot_of[match] = np.arange(len(gens))
    source_label = label[nodes]
    parent = search.pred[nodes + 1].astype(np.int64) - 1
    parent[(parent < 0) | (parent >= N)] = -1  # a source, or none
    inside = parent >= 0  # (a parent of another cell: joined to this cell's source)
    inside[inside] = label[parent[inside]] == source_label[inside]
    parent[~inside] = -1
    return _Forest(nodes, robot_of[source_label], search.dist[nodes + 1], parent)


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
    parent = np.full(N, -1, dtype=np.int64)
    for k in range(n):
        mask = label == k
        keep = star_shaped(mask, preds[k], first)
        label[mask & ~keep] = -1
        mine = np.flatnonzero(keep[1:first])
        parent[mine] = preds[k][mine + 1].astype(np.int64) - 1
    nodes = np.flatnonzero(label[1:first] >= 0)
    parent = parent[nodes]
    parent[(parent < 0) | (parent >= N)] = -1
    return _Forest(nodes, label[nodes + 1], own_d[nodes + 1], parent)


def _covectors(domain: CoverageDomain, forest: _Forest, grids: np.ndarray, wdA: np.ndarray,
               method: str, n: int) -> np.ndarray:
    """Steps 2-3: ``(n, 2)`` every robot's I_k (grid axes, chart units)."""
    nodes, k, g, parent = forest.nodes, forest.owner, forest.g, forest.parent
    m = len(nodes)
    if m == 0:
        return np.zeros((n, 2))
    # positions of the parents among the owned nodes; m: the root (joined to the source)
    pos = np.full(domain.shape[0] * domain.shape[1], m, dtype=np.int64)
    pos[nodes] = np.arange(m)
    up = np.where(parent >= 0, pos[np.maximum(parent, 0)], m)
    if method == "lookahead":
        flag = g <= LOOKAHEAD_CELLS * domain.graph.max_edge_cost
    else:
        flag = up == m
    anchor = np.append(np.where(flag, np.arange(m), up), m)  # (m + 1,), the root its own
    todo = np.flatnonzero(~flag)
    while len(todo):  # pointer doubling: a flagged node (or the root) is its own anchor
        nxt = anchor[anchor[todo]]
        moved = nxt != anchor[todo]
        anchor[todo] = nxt
        todo = todo[moved]
    anchor = anchor[:m]
    anchor = np.where(anchor == m, np.arange(m), anchor)  # no anchor: the chord to the cell
    pts = domain.node_centers(nodes[anchor])
    z = domain.chart_displacement(grids[k], pts)
    if domain.tensor is None and domain.zeta is None:
        Mz = z
    else:
        Mz = np.einsum("nij,nj->ni", domain.metric_at(grids)[k], z)
    norm = np.sqrt(np.einsum("ni,ni->n", z, Mz))
    ok = norm > 1e-12
    coef = g[ok] * wdA[ok] / norm[ok]
    return np.stack([np.bincount(k[ok], weights=coef * Mz[ok, 0], minlength=n),
                     np.bincount(k[ok], weights=coef * Mz[ok, 1], minlength=n)], axis=1)
