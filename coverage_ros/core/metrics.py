"""Coverage metrics.

* Coverage cost H = sum_k sum_{q in V_k} (d(q, p_k)^2 - R_k^2) w(q) dA (Bhattacharya et al. 2014,
  Eq. 1 with f_k(x) = x^2 - R_k^2), with the geodesic distance (and cells) or the Euclidean one.
* Cell masses M_k = sum_{q in V_k} w(q) dA and the mass deviation of Lee & Lee 2024, Eq. 9:
  I = 1/k sum_k |M_k / mean(M) - 1|.
* Sensor coverage: the part of the free space (or of the density mass) within ``radius`` and in
  line of sight of at least one robot (``coverage_ratio``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tangents import depth_bins, polar_depth, visible_from
from coverage_ros.core.world.grid import GridMap

if TYPE_CHECKING:  # the tessellation's graph searches import scipy: only where used
    from coverage_ros.core.geodesic.tessellation import Generator


def mass_deviation(masses: Sequence[float] | np.ndarray) -> float:
    """Lee & Lee 2024, Eq. 9: mean absolute relative deviation of the cell masses (0 =
    balanced)."""
    m = np.asarray(masses, dtype=np.float64)
    if m.size == 0 or m.mean() <= 0:
        return 0.0
    return float(np.mean(np.abs(m / m.mean() - 1.0)))


def euclidean_cost(domain: CoverageDomain, gens: Sequence[Generator]) -> float:
    from coverage_ros.core.geodesic.euclidean import euclidean_labels

    labels = euclidean_labels(domain, gens).ravel()
    ok = labels >= 0
    X, Y = domain.geometry.all_cell_centers()
    pts = np.stack([X.ravel(), Y.ravel()], axis=-1)[ok]
    lab = labels[ok]
    P = np.array([g.position for g in gens])
    R2 = np.array([g.weight ** 2 for g in gens])
    f = ((pts - P[lab]) ** 2).sum(axis=1) - R2[lab]
    return float((f * domain.mass_element.ravel()[ok]).sum())


def sensor_footprint(grid: GridMap, position: np.ndarray, radius: float) -> np.ndarray:
    """``(H, W) bool``: free cells within ``radius`` [m] of ``position`` and in line of sight
    of it (walls modelled as in :func:`coverage_ros.core.geodesic.tangents.polar_depth`)."""
    H, W = grid.shape
    out = np.zeros((H, W), dtype=bool)
    g = grid.world_to_grid(np.asarray(position, dtype=np.float64))
    rc = radius / grid.resolution
    c0, c1 = max(int(np.floor(g[0] - rc)) - 1, 0), min(int(np.ceil(g[0] + rc)) + 1, W)
    r0, r1 = max(int(np.floor(g[1] - rc)) - 1, 0), min(int(np.ceil(g[1] + rc)) + 1, H)
    if c0 >= c1 or r0 >= r1:
        return out
    rows, cols = np.mgrid[r0:r1, c0:c1]
    pts = np.stack([cols.ravel() + 0.5, rows.ravel() + 0.5], axis=-1)
    free = grid.free_mask()[r0:r1, c0:c1].ravel()
    near = np.hypot(*(pts - g).T) <= rc
    blocked = ~grid.free_mask()[r0:r1, c0:c1]
    br, bc = np.nonzero(blocked)
    depth = polar_depth(g, np.stack([bc + c0 + 0.5, br + r0 + 0.5], axis=-1).astype(float),
                        depth_bins(rc))
    seen = near & free
    seen[seen] = visible_from(g, pts[seen], depth)
    out[r0:r1, c0:c1] = seen.reshape(r1 - r0, c1 - c0)
    return out


def covered_mask(grid: GridMap, positions: np.ndarray,
                 radius: float | np.ndarray) -> np.ndarray:
    """``(H, W) bool``: the union of the robots' footprints (``radius`` [m]: one for all, or
    ``(n,)`` one per robot)."""
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    radii = np.broadcast_to(np.asarray(radius, dtype=np.float64), (len(P),))
    mask = np.zeros(grid.shape, dtype=bool)
    for p, r in zip(P, radii, strict=True):
        mask |= sensor_footprint(grid, p, float(r))
    return mask


def coverage_ratio(grid: GridMap, positions: np.ndarray, radius: float | np.ndarray) -> float:
    """Free area within sensor range and line of sight of some robot / all free area
    (``radius``: one for all, or one per robot)."""
    free = grid.free_mask()
    total = int(free.sum())
    return float(covered_mask(grid, positions, radius).sum() / total) if total else 0.0


def min_separation(positions: np.ndarray) -> float:
    """[m] smallest distance between two robots (inf for fewer than two)."""
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    if len(P) < 2:
        return float("inf")
    from scipy.spatial.distance import pdist  # scipy's import is a tenth of a second

    return float(pdist(P).min())
