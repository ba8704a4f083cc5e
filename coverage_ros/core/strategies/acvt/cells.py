"""Cells of Lee & Lee (2024, adaptive CVT) on the grid: partition, masses, centroids, the
projection of Eq. 8 and the metrics of Eq. 9, 13, 14 and 18.

One distance covers every variant of the paper. For a cell centre s and agent i at p_i::

    d_i(s) = (||T_c (s - p_i)|| + lambda * l_i(s)) / R_i

* Eq. 1 (plain Voronoi): T_c = identity, lambda = 0, R_i = 1.
* Eq. 15 (shape constraint): T_c = diag(a, b) weighs horizontal and vertical (map x / y)
  distances, and l_i(s) [m] is the length of the straight segment p_i -> s where rho = 0
  (outside the targets or on obstacles), penalised by lambda.
* Eq. 17 (heterogeneous agents): R_i = v_max,i * t is the agent's reach; the common t cancels
  in every comparison and in the metrics, so a reach in metres per 1 s is used.

Each cell goes to the agent of smallest d_i. With ``visibility`` (Eq. 11-12, and the
``cap L_{i,s}`` of Eq. 17) a cell that its agent cannot see is left *uncovered* (label -1); it
is not handed to another agent. Only cells of positive mass w dA are labelled, since masses and
centroids need nothing else; obstacles and the space outside the targets have rho = 0.

Eq. 8 (projection): a goal on a cell with rho = 0 moves to the centre of the nearest cell with
rho > 0 (one Euclidean distance transform per domain; ties are broken by scipy, not by the
paper's counter-clockwise search).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tangents import polar_depth, visible_from
from coverage_ros.core.metrics import mass_deviation
from coverage_ros.errors import ConfigError

#: A part of the density's support counts as a separate target from this share of the mass.
REGION_SHARE = 0.01

#: [cells] radial step of the rays along which the rho = 0 length l_i(s) of Eq. 15 is summed
#: (half a cell, so no cell is stepped over).
RAY_STEP_CELLS = 0.5
#: Fewest angular bins of those rays (more when the grid is large, see :func:`_ray_bins`).
MIN_RAY_BINS = 256
#: Entries (cells x agents) of one chunk of the distance matrix of a plain partition (8 MB).
CHUNK_ENTRIES = 1 << 20


@dataclass(frozen=True)
class CellSpec:
    """Which of the paper's cell definitions to use (defaults: plain Voronoi, Eq. 1)."""

    visibility: bool = False  # Eq. 11-12: keep only the part of the cell in line of sight
    scale: tuple[float, float] = (1.0, 1.0)  # (a, b) of T_c in Eq. 15, on map x and y
    gap_penalty: float = 0.0  # lambda of Eq. 15 [m of distance per m of rho = 0 crossed]

    def __post_init__(self) -> None:
        a, b = (float(v) for v in self.scale)
        if not (0.0 <= a <= 1.0 and 0.0 <= b <= 1.0 and a + b > 0.0):
            raise ConfigError.at("scale", "T_c weights (a, b) must lie in [0, 1], not both 0",
                                 self.scale)
        if not (math.isfinite(self.gap_penalty) and self.gap_penalty >= 0.0):
            raise ConfigError.at("gap_penalty", "must be a finite number >= 0", self.gap_penalty)
        object.__setattr__(self, "scale", (a, b))

    @property
    def plain(self) -> bool:
        """Whether d_i is the plain Euclidean distance (Eq. 1, up to the reach R_i)."""
        return self.scale == (1.0, 1.0) and self.gap_penalty == 0.0


class MassCells:
    """The domain's cells of positive mass, with what every partition of them needs.

    Attributes (N = number of cells with w dA > 0):
    ``nodes (N,) int64`` node ids (row * W + col); ``grid (N, 2)`` centres in grid
    coordinates [cells]; ``xy (N, 2)`` centres in the map frame [m]; ``wdA (N,)`` masses;
    ``total`` their sum (the integral of rho over S in Eq. 14).
    """

    def __init__(self, domain: CoverageDomain) -> None:
        self.domain = domain
        feasible = domain.mass_element > 0
        if not feasible.any():
            raise ConfigError.at("density", "is zero everywhere on the free space; alpha-CVT "
                                 "needs a target with rho > 0")
        self.feasible = feasible
        self.nodes = np.flatnonzero(feasible.ravel())
        self.grid = domain.node_centers(self.nodes)
        self.xy = domain.to_map(self.grid)
        self.wdA = domain.mass_element.ravel()[self.nodes]
        self.total = float(self.wdA.sum())
        self._centre = self.xy.mean(axis=0)
        self._xy_centred = self.xy - self._centre
        # (N, 4): (|s|^2, x, y, 1) about the centre, the rows of the partition over reaches
        self._features = np.column_stack([(self._xy_centred ** 2).sum(axis=1),
                                          self._xy_centred, np.ones(len(self.nodes))])
        # (N,) first moments of the masses, each contiguous for bincount
        self._wx, self._wy = self.wdA * self.xy[:, 0], self.wdA * self.xy[:, 1]
        _, self._nearest = ndimage.distance_transform_edt(~feasible, return_indices=True)
        self._zero = domain.density <= 0.0  # rho = 0: outside the targets and on obstacles

    @functools.cached_property
    def regions(self) -> int:
        """Disjoint parts of the support of rho (rho > 0 on free space, 8-connected) that hold
        at least :data:`REGION_SHARE` of the total mass: Lee & Lee's separate targets."""
        return len(self.region_masses)

    @functools.cached_property
    def region_of_cells(self) -> np.ndarray:
        """``(N,) int64``: the target (index into :attr:`region_masses`, largest part first) of
        every mass cell; -1 in a part below :data:`REGION_SHARE` of the mass."""
        parts, count = ndimage.label(self.feasible, structure=np.ones((3, 3), dtype=bool))
        part = parts.ravel()[self.nodes] - 1
        mass = np.bincount(part, weights=self.wdA, minlength=count)
        kept = np.flatnonzero(mass >= REGION_SHARE * self.total)
        kept = kept[np.argsort(-mass[kept], kind="stable")]
        index = np.full(count, -1, dtype=np.int64)
        index[kept] = np.arange(len(kept))
        regions: np.ndarray = index[part]
        return regions

    @functools.cached_property
    def region_masses(self) -> np.ndarray:
        """``(R,)``: the mass of every target, largest first."""
        ok = self.region_of_cells >= 0
        return np.bincount(self.region_of_cells[ok], weights=self.wdA[ok])

    # ------------------------------------------------------------------ Eq. 8
    def project(self, points: np.ndarray) -> np.ndarray:
        """Eq. 8: ``(k, 2)`` map-frame points, each moved to the centre of the nearest cell
        with rho > 0 unless it already lies on one."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        g = self.domain.to_grid(pts)
        H, W = self.domain.shape
        col = np.floor(g[:, 0]).astype(np.int64)
        row = np.floor(g[:, 1]).astype(np.int64)
        inside = (row >= 0) & (row < H) & (col >= 0) & (col < W)
        row, col = np.clip(row, 0, H - 1), np.clip(col, 0, W - 1)
        ok = inside & self.feasible[row, col]
        out = pts.copy()
        bad = ~ok
        if bad.any():
            r = self._nearest[0, row[bad], col[bad]]
            c = self._nearest[1, row[bad], col[bad]]
            out[bad] = self.domain.to_map(np.stack([c + 0.5, r + 0.5], axis=-1))
        return out

    # ------------------------------------------------------------------ partition
    def distance(self, position: np.ndarray, reach: float | None, spec: CellSpec,
                 cells: np.ndarray | None = None) -> np.ndarray:
        """``(n,)`` d_i(s) [m, divided by R_i] from one agent at ``position (2,)`` to the
        cells ``cells`` (indices into the N mass cells; all by default)."""
        xy = self.xy if cells is None else self.xy[cells]
        a, b = spec.scale
        diff = xy - np.asarray(position, dtype=np.float64)
        d = np.sqrt((a * diff[:, 0]) ** 2 + (b * diff[:, 1]) ** 2)
        if spec.gap_penalty > 0.0:
            origin = self.domain.to_grid(position)[0]
            grid = self.grid if cells is None else self.grid[cells]
            d += (spec.gap_penalty * self.domain.resolution) * gap_lengths(self._zero, origin,
                                                                           grid)
        if reach is not None:
            d /= float(reach)
        return d

    def labels(self, positions: np.ndarray, reach: np.ndarray | None = None,
               spec: CellSpec | None = None) -> np.ndarray:
        """``(N,) int64``: the agent (index into ``positions (k, 2)``) of every mass cell,
        -1 where the owner cannot see it (``spec.visibility``). ``reach (k,)`` [m] or None.
        Ties go to the lowest index."""
        spec = spec or CellSpec()
        P = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        if spec.plain and reach is None:
            # Plain Voronoi: argmin_i |p_i|^2 - 2 s.p_i (one matrix product per chunk of
            # cells, about centred coordinates for precision); equal columns of coincident
            # agents tie and argmin takes the lowest index.
            Pc = P - self._centre
            out = np.empty(len(self.nodes), dtype=np.int64)
            sq = (Pc * Pc).sum(axis=1)
            step = max(1, CHUNK_ENTRIES // max(len(P), 1))
            for s in range(0, len(self.nodes), step):
                d = self._xy_centred[s:s + step] @ (-2.0 * Pc.T)
                d += sq
                out[s:s + step] = np.argmin(d, axis=1)
        elif spec.plain:
            # Plain distances over reaches (Eq. 17): argmin_i |s - p_i|^2 / R_i^2, expanded as
            # |s|^2 w_i - 2 s.p_i w_i + |p_i|^2 w_i with w_i = 1 / R_i^2 (one matrix product per
            # chunk of cells, about centred coordinates): the order of d_i(s) / R_i but for
            # rounding at near ties. Equal columns (coincident agents of one reach) tie and
            # argmin takes the lowest index.
            Pc = P - self._centre
            w = 1.0 / np.asarray(reach, dtype=np.float64) ** 2
            A = np.stack([w, -2.0 * w * Pc[:, 0], -2.0 * w * Pc[:, 1], w * (Pc * Pc).sum(1)])
            out = np.empty(len(self.nodes), dtype=np.int64)
            step = max(1, CHUNK_ENTRIES // max(len(P), 1))
            for s in range(0, len(self.nodes), step):
                out[s:s + step] = np.argmin(self._features[s:s + step] @ A, axis=1)
        else:
            best = np.full(len(self.nodes), np.inf)
            out = np.zeros(len(self.nodes), dtype=np.int64)
            for i, p in enumerate(P):  # running minimum: O(N) memory for any team
                d = self.distance(p, None if reach is None else reach[i], spec)
                better = d < best
                best[better] = d[better]
                out[better] = i
        if spec.visibility:
            out = self.restrict_to_visible(out, P)
        return out

    def restrict_to_visible(self, labels: np.ndarray, positions: np.ndarray,
                            agents: Sequence[int] | None = None) -> np.ndarray:
        """Eq. 12: ``labels`` with the cells of ``agents`` (all by default) that their agent
        cannot see set to -1."""
        out = labels.copy()
        P = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        occluders = self.domain.occluder_centers  # (M, 2) grid centres, made once per domain
        for i in range(len(P)) if agents is None else agents:
            own = np.flatnonzero(out == i)
            if len(own) == 0 or len(occluders) == 0:
                continue
            # The same line-of-sight model as CoverageDomain.visible_mask, over the whole map.
            origin = self.domain.to_grid(P[i])[0]
            depth = polar_depth(origin, occluders, self.domain.depth_bins)
            out[own[~visible_from(origin, self.grid[own], depth)]] = -1
        return out

    def stats(self, labels: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """``(masses (k,), centroids (k, 2))`` of the labelled cells (Eq. 3a-3b); the centroid
        of an empty cell is NaN."""
        if labels.min(initial=0) >= 0:
            lab, w, wx, wy = labels, self.wdA, self._wx, self._wy
        else:
            ok = labels >= 0
            lab, w, wx, wy = labels[ok], self.wdA[ok], self._wx[ok], self._wy[ok]
        m = np.bincount(lab, weights=w, minlength=k)[:k]
        sx = np.bincount(lab, weights=wx, minlength=k)[:k]
        sy = np.bincount(lab, weights=wy, minlength=k)[:k]
        with np.errstate(invalid="ignore", divide="ignore"):
            c = np.stack([sx / m, sy / m], axis=-1)
        c[m <= 0] = np.nan
        return m, c

    def cost(self, labels: np.ndarray, positions: np.ndarray, agent: int) -> float:
        """Eq. 3c: sum over the agent's cells of |s - p_i|^2 w dA."""
        own = labels == agent
        d2 = ((self.xy[own] - np.asarray(positions)[agent]) ** 2).sum(axis=1)
        return float((d2 * self.wdA[own]).sum())


def gap_lengths(zero: np.ndarray, origin: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``(N,)`` [cells]: length of the straight segment ``origin -> points[n]`` (grid
    coordinates) over cells where ``zero (H, W)`` is True (Eq. 15's l_i(s) / resolution).

    Rays are cast from ``origin`` in angular bins with a step of :data:`RAY_STEP_CELLS`; the
    running length of rho = 0 along each ray is read at every point's distance, so one agent
    costs O(bins * radius) whatever the number of points. Samples off the grid count as zero.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return np.zeros(0)
    d = pts - origin
    dist = np.hypot(d[:, 0], d[:, 1])
    rmax = float(dist.max())
    bins = _ray_bins(rmax)
    h = RAY_STEP_CELLS
    steps = int(math.ceil(rmax / h)) + 1
    dx, dy = _ray_offsets(bins, steps)
    H, W = zero.shape
    col = np.floor(dx + origin[0]).astype(np.int64)
    row = np.floor(dy + origin[1]).astype(np.int64)
    inside = (row >= 0) & (row < H) & (col >= 0) & (col < W)
    z = np.ones(dx.shape, dtype=bool)
    z[inside] = zero[row[inside], col[inside]]
    cum = np.zeros((bins, steps + 1))
    np.cumsum(z, axis=1, out=cum[:, 1:])
    cum *= h
    b = (np.floor((np.arctan2(d[:, 1], d[:, 0]) + math.pi) / (2.0 * math.pi / bins))
         .astype(np.int64) % bins)
    f = dist / h
    j = np.minimum(np.floor(f).astype(np.int64), steps - 1)
    frac = f - j
    integral: np.ndarray = cum[b, j] + frac * (cum[b, j + 1] - cum[b, j])
    return integral


@functools.lru_cache(maxsize=4)
def _ray_offsets(bins: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """``(bins, steps)`` x and y offsets [cells] of the ray sample points (step midpoints)."""
    theta = -math.pi + (np.arange(bins) + 0.5) * (2.0 * math.pi / bins)
    r = (np.arange(steps) + 0.5) * RAY_STEP_CELLS
    return np.cos(theta)[:, None] * r[None, :], np.sin(theta)[:, None] * r[None, :]


def _ray_bins(radius_cells: float) -> int:
    """Angular bins so that neighbouring rays are at most a cell apart at ``radius_cells``."""
    return int(2 ** math.ceil(math.log2(max(2.0 * math.pi * radius_cells, MIN_RAY_BINS))))


# ---------------------------------------------------------------------------- metrics
def uncovered_deviation(masses: np.ndarray, total: float) -> float:
    """Eq. 14: I_c = (total - sum M_i) / (k * mean M_i), the uncovered mass relative to the
    covered mass (0 when the visible cells cover every target cell, inf when none does)."""
    m = np.asarray(masses, dtype=np.float64)
    covered = float(m.sum())
    if covered <= 0.0:
        return math.inf if total > 0 else 0.0
    return max(float(total) - covered, 0.0) / covered


def visible_mass_deviation(masses: np.ndarray, total: float) -> float:
    """Eq. 13: I^L = I + I_c of the visible-cell masses."""
    return mass_deviation(masses) + uncovered_deviation(masses, total)


def normalized_masses(masses: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """Eq. 18: M^h_i = M_i / (pi R_i^2), the mass per unit of the agent's reachable area."""
    R = np.asarray(reach, dtype=np.float64)
    return np.asarray(masses, dtype=np.float64) / (math.pi * R * R)


def heterogeneous_deviation(masses: np.ndarray, reach: np.ndarray, total: float,
                            visibility: bool = False) -> float:
    """Eq. 18: I^H = 1/k sum |M^h_i / mean(M^h) - 1| (+ I_c with visibility).

    The paper prints mean(M_V) in the denominator and defines mean(M^h_V) right below it; the
    latter is used, so that I^H is 0 when every agent's mass is proportional to R_i^2.
    """
    value = mass_deviation(normalized_masses(masses, reach))
    return value + (uncovered_deviation(masses, total) if visibility else 0.0)


def deviation_metric(masses: np.ndarray, total: float, reach: np.ndarray | None,
                     visibility: bool) -> float:
    """The paper's metric for a scenario: I (Eq. 9), I^L (Eq. 13) or I^H (Eq. 18)."""
    if reach is not None:
        return heterogeneous_deviation(masses, reach, total, visibility)
    if visibility:
        return visible_mass_deviation(masses, total)
    return mass_deviation(masses)
