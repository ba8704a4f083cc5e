"""Euclidean (power) Voronoi cells and centroids on the grid: the classic Lloyd baseline
(Cortes, Martinez, Karatas & Bullo 2004), on the same coverage domain as the geodesic cells.

The cell of generator i is every free cell q with
``|q - p_i|^2 - R_i^2 <= |q - p_j|^2 - R_j^2`` for all j, which ignores walls (a cell may lie
behind one); that is what the other strategies build on and what the geodesic method improves.
The decentralized computation clips the map rectangle by the bisector half-planes of the
known neighbours (a convex polygon), so it only looks at the cells inside that polygon.

A centroid that falls on an obstacle or outside the targets (density 0) is *projected* to the
nearest cell of the own cell with positive density (else the nearest free cell of the own cell).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tessellation import Generator


@dataclass(frozen=True)
class EuclideanCell:
    nodes: np.ndarray  # (n,) int64 node ids
    mass: float  # sum w dA
    cost: float  # sum (|q - p|^2 - R^2) w dA
    centroid: np.ndarray  # (2,) [m] mass centroid (map frame), may be infeasible
    goal: np.ndarray  # (2,) [m] centroid projected to a feasible cell
    polygon: np.ndarray  # (M, 2) [m] the convex cell before intersecting with free space

    @property
    def control(self) -> np.ndarray:
        return self.goal


def clip_polygon(poly: np.ndarray, normal: np.ndarray, offset: float) -> np.ndarray:
    """Sutherland-Hodgman: the part of convex ``poly (M, 2)`` with ``normal . x <= offset``."""
    if len(poly) == 0:
        return poly
    side = poly @ normal - offset
    out = []
    for k in range(len(poly)):
        a, b = poly[k], poly[(k + 1) % len(poly)]
        sa, sb = side[k], side[(k + 1) % len(poly)]
        if sa <= 0:
            out.append(a)
        if (sa <= 0) != (sb <= 0):
            t = sa / (sa - sb)
            out.append(a + t * (b - a))
    return np.array(out).reshape(-1, 2)


def power_cell_polygon(domain: CoverageDomain, own: Generator,
                       others: Sequence[Generator]) -> np.ndarray:
    """The own power cell clipped to the map's bounding rectangle, ``(M, 2)`` map frame."""
    xmin, ymin, xmax, ymax = domain.geometry.extent()
    poly = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
    p, r = own.position, own.weight
    for o in others:
        q = o.position
        if np.allclose(q, p):
            continue
        # |x-p|^2 - r^2 <= |x-q|^2 - rq^2  <=>  2 (q - p) . x <= |q|^2 - |p|^2 - rq^2 + r^2
        poly = clip_polygon(poly, 2.0 * (q - p), q @ q - p @ p - o.weight ** 2 + r * r)
        if len(poly) == 0:
            break
    return poly


def euclidean_cell(domain: CoverageDomain, own: Generator,
                   others: Sequence[Generator]) -> EuclideanCell:
    """Decentralized Euclidean power cell, its mass, cost and (projected) centroid."""
    poly = power_cell_polygon(domain, own, others)
    H, W = domain.shape
    if len(poly) == 0:
        return EuclideanCell(np.zeros(0, np.int64), 0.0, 0.0, own.position.copy(),
                             own.position.copy(), poly)
    g = domain.to_grid(poly)
    c0, c1 = max(int(np.floor(g[:, 0].min())) - 1, 0), min(int(np.ceil(g[:, 0].max())) + 1, W)
    r0, r1 = max(int(np.floor(g[:, 1].min())) - 1, 0), min(int(np.ceil(g[:, 1].max())) + 1, H)
    rows, cols = np.mgrid[r0:r1, c0:c1]
    nodes = (rows * W + cols).ravel()
    nodes = nodes[domain.free.ravel()[nodes]]
    xy = domain.to_map(domain.node_centers(nodes))
    d_own = ((xy - own.position) ** 2).sum(axis=1) - own.weight ** 2
    keep = np.ones(len(nodes), dtype=bool)
    for o in others:
        keep &= d_own <= ((xy - o.position) ** 2).sum(axis=1) - o.weight ** 2
    nodes, xy, d_own = nodes[keep], xy[keep], d_own[keep]
    wdA = domain.mass_element.ravel()[nodes]
    mass = float(wdA.sum())
    cost = float((d_own * wdA).sum())
    if mass > 0:
        centroid = (xy * wdA[:, None]).sum(axis=0) / mass
    else:
        centroid = own.position.copy()
    goal = project_feasible(domain, centroid, nodes, xy, wdA)
    return EuclideanCell(nodes, mass, cost, centroid, goal, poly)


def project_feasible(domain: CoverageDomain, point: np.ndarray, nodes: np.ndarray,
                     xy: np.ndarray, wdA: np.ndarray) -> np.ndarray:
    """``point`` if it lies on a free cell with positive density; else the nearest own-cell
    cell centre with positive density (or, lacking one, the nearest own-cell cell)."""
    g = domain.to_grid(point)[0]
    H, W = domain.shape
    r, c = int(np.floor(g[1])), int(np.floor(g[0]))
    if 0 <= r < H and 0 <= c < W and domain.free[r, c] and domain.density[r, c] > 0:
        return point
    if len(nodes) == 0:
        return point
    cand = wdA > 0
    pool = xy[cand] if cand.any() else xy
    nearest: np.ndarray = pool[int(np.argmin(((pool - point) ** 2).sum(axis=1)))].copy()
    return nearest


def cell_cost_about(domain: CoverageDomain, nodes: np.ndarray, point: np.ndarray,
                    weight: float) -> float:
    """Coverage cost sum (|q - point|^2 - R^2) w dA of the fixed cell ``nodes`` about
    ``point`` (2,) [m]."""
    xy = domain.to_map(domain.node_centers(nodes))
    f = ((xy - point) ** 2).sum(axis=1) - weight ** 2
    return float((f * domain.mass_element.ravel()[nodes]).sum())


def euclidean_labels(domain: CoverageDomain, gens: Sequence[Generator]) -> np.ndarray:
    """``(H, W) int64``: centralized Euclidean power Voronoi labels of the free cells
    (-1 on blocked cells)."""
    X, Y = domain.geometry.all_cell_centers()
    pts = np.stack([X.ravel(), Y.ravel()], axis=-1)
    P = np.array([g.position for g in gens])
    R2 = np.array([g.weight ** 2 for g in gens])
    best = np.full(len(pts), np.inf)
    labels = np.full(len(pts), -1, dtype=np.int64)
    for k in range(len(gens)):
        d = ((pts - P[k]) ** 2).sum(axis=1) - R2[k]
        better = d < best
        best[better] = d[better]
        labels[better] = k
    labels[~domain.free.ravel()] = -1
    return labels.reshape(domain.shape)
