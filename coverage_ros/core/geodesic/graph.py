"""Grid graphs whose edge costs are metric lengths (Bhattacharya et al. 2014, section 4).

Vertices are the cells of a ``(H, W)`` grid, numbered ``node = row * W + col``; blocked cells are
isolated vertices. Edges join a cell to its neighbours in an 8-connected (the paper's) or
16-connected neighbourhood (adds the knight moves, which cut the metric's worst-case anisotropy
from 8.2 % to 2.7 %). An edge exists only if both end cells and every cell the straight segment
between their centres passes through are free, so paths never cut an obstacle's corner.

Edge cost = metric length of the edge, in chart units (metres for maps):

* Euclidean: ``|v|`` with ``v = (dcol, drow) * resolution``;
* isotropic weight ``zeta(q)`` (metric tensor ``zeta * I``, Bhattacharya et al. 2014 Eq. 9):
  ``|v| * (sqrt(zeta_u) + sqrt(zeta_v)) / 2``;
* metric tensor ``eta(q)`` ``(H, W, 2, 2)`` in ``(x, y) = (col, row)`` chart coordinates:
  ``(sqrt(v' eta_u v) + sqrt(v' eta_v v)) / 2``.

Charts of closed surfaces wrap around (``wrap=(rows, cols)``) and may carry extra edges, e.g.
across a cordoned-off pole of a sphere (section 4.1).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from functools import cached_property, partial
from typing import TYPE_CHECKING, Any

import numpy as np

from coverage_ros.errors import ConfigError

if TYPE_CHECKING:
    from scipy.sparse import csr_matrix

#: (drow, dcol) offsets, counter-clockwise from east.
NEIGHBOURHOOD_8 = ((0, 1), (1, 1), (1, 0), (1, -1), (0, -1), (-1, -1), (-1, 0), (-1, 1))
NEIGHBOURHOOD_16 = NEIGHBOURHOOD_8 + ((1, 2), (2, 1), (2, -1), (1, -2),
                                      (-1, -2), (-2, -1), (-2, 1), (-1, 2))


def neighbourhood(connectivity: int) -> np.ndarray:
    if connectivity == 8:
        return np.array(NEIGHBOURHOOD_8, dtype=np.int64)
    if connectivity == 16:
        return np.array(NEIGHBOURHOOD_16, dtype=np.int64)
    raise ConfigError.at("connectivity", "unsupported grid neighbourhood", connectivity, "8 or 16")


def swept_cells(dr: int, dc: int) -> list[tuple[int, int]]:
    """Cells (relative offsets) that the segment between the centres of cell (0, 0) and cell
    (dr, dc) passes through or touches, excluding the two end cells."""
    if abs(dr) <= 1 and abs(dc) <= 1:
        return [(dr, 0), (0, dc)] if dr and dc else []
    t = np.linspace(0.0, 1.0, 4001)
    pts = np.stack([0.5 + t * dr, 0.5 + t * dc], axis=-1)
    eps = 1e-9
    cells = set()
    for sr in (-eps, eps):
        for sc in (-eps, eps):
            for r, c in np.floor(pts + np.array([sr, sc])).astype(int):
                cells.add((int(r), int(c)))
    cells.discard((0, 0))
    cells.discard((dr, dc))
    return sorted(cells)


def shift(a: np.ndarray, dr: int, dc: int, wrap: tuple[bool, bool], fill: float) -> np.ndarray:
    """``out[r, c] = a[r + dr, c + dc]`` (wrapping or filled beyond the edges)."""
    out = a
    if dr:
        if wrap[0]:
            out = np.roll(out, -dr, axis=0)
        else:
            pad = np.full((abs(dr),) + out.shape[1:], fill, dtype=out.dtype)
            out = (np.concatenate([out[dr:], pad], axis=0) if dr > 0
                   else np.concatenate([pad, out[:dr]], axis=0))
    if dc:
        if wrap[1]:
            out = np.roll(out, -dc, axis=1)
        else:
            pad = np.full((out.shape[0], abs(dc)) + out.shape[2:], fill, dtype=out.dtype)
            out = (np.concatenate([out[:, dc:], pad], axis=1) if dc > 0
                   else np.concatenate([pad, out[:, :dc]], axis=1))
    return out


@dataclass(frozen=True, eq=False)
class GridGraph:
    """A metric grid graph (see module docstring). Build with :func:`build_grid_graph`."""

    free: np.ndarray  # (H, W) bool
    resolution: float  # chart units (m) per cell
    offsets: np.ndarray  # (K, 2) int (drow, dcol)
    #: makes :attr:`cost` on first use: a Euclidean Lloyd team never searches the graph, and
    #: the (H, W, K) array is most of a large domain's set-up
    costs: Callable[[], np.ndarray]
    wrap: tuple[bool, bool] = (False, False)
    extra_edges: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # (u, v, cost) undirected
    area: np.ndarray | None = None  # (H, W) cell volume element sqrt(det eta) * res^2; None=res^2
    euclidean: bool = True  # True when the metric is the plain Euclidean one
    _cache: dict[Hashable, Any] = field(default_factory=dict, repr=False)

    @cached_property
    def cost(self) -> np.ndarray:
        """``(H, W, K)`` float64 edge lengths; inf where there is no edge."""
        return self.costs()

    @property
    def shape(self) -> tuple[int, int]:
        H, W = self.free.shape
        return H, W

    @property
    def num_nodes(self) -> int:
        return int(self.free.size)

    @cached_property
    def max_edge_cost(self) -> float:
        finite = self.cost[np.isfinite(self.cost)]
        return float(finite.max()) if finite.size else 0.0

    def cell_area(self) -> np.ndarray:
        """``(H, W)`` area element of every cell (m^2 for maps)."""
        if self.area is not None:
            return self.area
        return np.full(self.shape, self.resolution ** 2)

    def neighbour_index(self, k: int) -> np.ndarray:
        """``(H, W) int64``: node id of each cell's neighbour along offset ``k`` (-1 if none)."""
        key = ("nb", k)
        if key not in self._cache:
            H, W = self.shape
            ids = np.arange(H * W, dtype=np.int64).reshape(H, W)
            dr, dc = (int(v) for v in self.offsets[k])
            self._cache[key] = shift(ids, dr, dc, self.wrap, -1)
        index: np.ndarray = self._cache[key]
        return index

    @cached_property
    def edge_table(self) -> tuple[np.ndarray, np.ndarray]:
        """``(nb, cost)``, each ``(N + 1, K)``: neighbour node of every node along each offset
        (``N``, a sentinel, where there is no edge) and the edge cost (inf there). Row ``N`` is
        the sentinel's own row. Local searches gather rows of these tables."""
        N, K = self.num_nodes, len(self.offsets)
        nb = np.full((N + 1, K), N, dtype=np.int32 if N < 2**31 - 1 else np.int64)
        cost = np.full((N + 1, K), np.inf)
        for k in range(K):
            c = self.cost[..., k].ravel()
            ok = np.isfinite(c)
            nb[:N, k] = np.where(ok, self.neighbour_index(k).ravel(), N)
            cost[:N, k] = c
        return nb, cost

    @cached_property
    def edge_bits(self) -> np.ndarray:
        """``(N + 1,)`` bit k set when a node has an edge along offset k (uint8 for 8
        neighbours, uint16 for 16); the sentinel N has none."""
        K = len(self.offsets)
        bits: np.ndarray = np.zeros(self.num_nodes + 1, dtype=np.uint8 if K <= 8 else np.uint16)
        for k in range(K):
            ok = np.isfinite(self.cost[..., k].ravel())
            bits[:-1] |= (ok.astype(bits.dtype) << k)
        return bits

    @cached_property
    def offset_steps(self) -> np.ndarray:
        """``(K,)`` node-id difference of each offset (without wrap-around)."""
        steps: np.ndarray = self.offsets[:, 0] * self.shape[1] + self.offsets[:, 1]
        return steps.astype(np.int64)

    @cached_property
    def uniform_costs(self) -> np.ndarray | None:
        """``(K,)`` edge length per offset when every edge along an offset has the same cost
        (Euclidean metric), else None."""
        if not self.euclidean:
            return None
        return np.array([offset_length(int(dr), int(dc), self.resolution)
                         for dr, dc in self.offsets])

    @cached_property
    def offset_costs(self) -> np.ndarray | None:
        """``(K,)`` the cost of the edges along each offset, as :attr:`edge_table` holds
        them, when every edge along an offset costs the same (a uniform metric), else None."""
        _, cost = self.edge_table
        costs = np.full(cost.shape[1], np.inf)  # (an offset without edges: never read)
        for k in range(cost.shape[1]):
            c = cost[:, k]
            c = c[np.isfinite(c)]
            if len(c) and (c != c[0]).any():
                return None
            if len(c):
                costs[k] = c[0]
        return costs

    @cached_property
    def csr(self) -> csr_matrix:
        """The whole graph as a ``(N, N)`` CSR matrix of edge costs (directed both ways), each
        row's columns ascending."""
        from scipy.sparse import csr_matrix  # scipy's import is a tenth of a second

        N, K = self.num_nodes, len(self.offsets)
        if self.extra_edges is None and not any(self.wrap):
            # Without wrap-around a neighbour's id is the node's plus its offset's step, and
            # the steps in ascending order give each row's columns in order: no sort needed.
            order = np.argsort(self.offset_steps, kind="stable")
            cost = self.cost.reshape(N, K)[:, order]
            ok = np.isfinite(cost)
            cols = np.arange(N, dtype=np.int64)[:, None] + self.offset_steps[order][None, :]
            indptr = np.zeros(N + 1, dtype=np.int32)
            np.cumsum(ok.sum(axis=1), out=indptr[1:])
            return csr_matrix((cost[ok], cols[ok].astype(np.int32), indptr), shape=(N, N))
        rows, cols, data = [], [], []
        ids = np.arange(N, dtype=np.int64)
        for k in range(K):
            c = self.cost[..., k].ravel()
            ok = np.isfinite(c)
            rows.append(ids[ok])
            cols.append(self.neighbour_index(k).ravel()[ok])
            data.append(c[ok])
        if self.extra_edges is not None:
            u, v, w = self.extra_edges
            rows += [u, v]
            cols += [v, u]
            data += [w, w]
        r = np.concatenate(rows)
        order = np.lexsort((np.concatenate(cols), r))
        r = r[order]
        cidx = np.concatenate(cols)[order].astype(np.int32)
        d = np.concatenate(data)[order]
        indptr = np.zeros(N + 1, dtype=np.int32)
        np.cumsum(np.bincount(r, minlength=N), out=indptr[1:])
        return csr_matrix((d, cidx, indptr), shape=(N, N))

    def node_of_cell(self, cells: np.ndarray) -> np.ndarray:
        c = np.asarray(cells, dtype=np.int64)
        return c[..., 0] * self.shape[1] + c[..., 1]

def build_grid_graph(free: np.ndarray, resolution: float, connectivity: int = 8,
                     zeta: np.ndarray | None = None, tensor: np.ndarray | None = None,
                     wrap: tuple[bool, bool] = (False, False),
                     extra_edges: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
                     ) -> GridGraph:
    """Build the graph over ``free`` cells (see module docstring for the edge costs)."""
    free = np.asarray(free, dtype=bool)
    if free.ndim != 2:
        raise ConfigError.at("free", "must be a 2-D mask", free.shape)
    if not resolution > 0:
        raise ConfigError.at("resolution", "must be > 0", resolution)
    if zeta is not None and tensor is not None:
        raise ConfigError("give either an isotropic weight zeta or a metric tensor, not both")
    offsets = neighbourhood(connectivity)
    H, W = free.shape
    sqrt_zeta = None
    if zeta is not None:
        zeta = np.asarray(zeta, dtype=np.float64)
        if zeta.shape != free.shape or np.any(~np.isfinite(zeta)) or np.any(zeta <= 0):
            raise ConfigError.at("zeta", "must be a finite, positive (H, W) array", zeta.shape,
                                 str(free.shape))
        sqrt_zeta = np.sqrt(zeta)
    if tensor is not None:
        tensor = np.asarray(tensor, dtype=np.float64)
        if tensor.shape != (H, W, 2, 2) or not np.all(np.isfinite(tensor)):
            raise ConfigError.at("tensor", "must be a finite (H, W, 2, 2) array", tensor.shape)
        det = tensor[..., 0, 0] * tensor[..., 1, 1] - tensor[..., 0, 1] * tensor[..., 1, 0]
        if np.any(det <= 0) or np.any(tensor[..., 0, 0] <= 0):
            raise ConfigError("tensor: every metric tensor must be positive definite")
    area = None
    euclidean = zeta is None and tensor is None
    if tensor is not None:
        det = tensor[..., 0, 0] * tensor[..., 1, 1] - tensor[..., 0, 1] * tensor[..., 1, 0]
        area = np.sqrt(det) * resolution ** 2
    elif zeta is not None:
        area = zeta * resolution ** 2
    if extra_edges is not None:
        u, v, w = (np.asarray(a) for a in extra_edges)
        extra_edges = (u.astype(np.int64), v.astype(np.int64), w.astype(np.float64))
    return GridGraph(free=free, resolution=float(resolution), offsets=offsets,
                     costs=partial(_edge_costs, free, float(resolution), offsets, wrap,
                                   sqrt_zeta, tensor),
                     wrap=wrap, extra_edges=extra_edges, area=area, euclidean=euclidean)


def offset_length(dr: int, dc: int, resolution: float) -> float:
    """[m] the straight length of the offset ``(dr, dc)`` cells, rounded one way wherever an
    edge's cost is made (a local search's edges and the whole graph's then agree bit for bit)."""
    return float(np.hypot(dc * resolution, dr * resolution))


def _edge_costs(free: np.ndarray, resolution: float, offsets: np.ndarray,
                wrap: tuple[bool, bool], sqrt_zeta: np.ndarray | None,
                tensor: np.ndarray | None) -> np.ndarray:
    """``(H, W, K)`` the metric length of every edge of :func:`build_grid_graph` (module
    docstring), inf where there is none."""
    H, W = free.shape
    cost = np.full((H, W, len(offsets)), np.inf)
    for k, (dr, dc) in enumerate(offsets):
        ok = free & shift(free, dr, dc, wrap, False)
        for sr, sc in swept_cells(int(dr), int(dc)):
            ok &= shift(free, sr, sc, wrap, False)
        v = np.array([dc, dr], dtype=np.float64) * resolution  # (x, y) chart displacement
        length = offset_length(int(dr), int(dc), resolution)
        if tensor is not None:
            q = np.sqrt(np.einsum("i,hwij,j->hw", v, tensor, v))
            c = 0.5 * (q + shift(q, dr, dc, wrap, np.inf))
        elif sqrt_zeta is not None:
            c = length * 0.5 * (sqrt_zeta + shift(sqrt_zeta, dr, dc, wrap, np.inf))
        else:
            c = np.full((H, W), length)
        cost[..., k] = np.where(ok, c, np.inf)
    return cost


def octile_bound(connectivity: int) -> float:
    """Worst-case ratio of graph distance to true distance in free space for a neighbourhood
    (1/cos of half the largest angle between adjacent move directions)."""
    angles = sorted({math.atan2(dr, dc) % (2 * math.pi) for dr, dc in neighbourhood(connectivity)})
    gaps = np.diff(angles + [angles[0] + 2 * math.pi])
    return 1.0 / math.cos(0.5 * float(gaps.max()))
