"""The deadlock-aware guided map of Wang et al. (2024, Sec. IV-C).

Each control period a robot picks a goal ``p_g``, the highest-density point within sensing
range that it can reach in what it remembers of its scans (:mod:`.memory`;
:func:`local_maximum_goal`), and computes the navigation function ``M_go``, the cost-to-go to
``p_g`` over the remembered free space inflated by the robot radius (:func:`local_map`,
:func:`navigation_function`: Dijkstra backwards from the goal with scipy's csgraph on an
8-connected grid that never cuts a corner). ``M_go`` has no local minimum but the goal
(Lemma 2), so the density ``phi = exp(-gamma M_go)`` (Eq. 8) pulls the centroid of the robot's
buffered cell along the shortest known path, around the walls it has seen instead of into them.

Coordinates: points ``(N, 2) float64`` [m] map frame; window cells ``(row, col)`` of the
memory's grid (:class:`~.memory.ObstacleMemory`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.strategies.bvc.memory import ObstacleMemory

#: Relative density margin by which a new local maximum must beat the current goal before the
#: goal moves (two nearly equal peaks would otherwise make the goal flip between them).
GOAL_HYSTERESIS = 0.02
#: [m] weight of a graph edge into or out of a blocked cell: longer than any path in a window,
#: so such edges are never used (the window graph keeps its structure; see WindowGraph).
BLOCKED_COST = 1e9
#: First Dijkstra limit as a multiple of the robot's cell reach: the goal lies within sensing
#: range, so in open space the robot is at most one reach from it and every cell point at most
#: two; two and a half leaves room for a detour before the search has to be redone without limit.
FIRST_LIMIT_FACTOR = 2.5


@dataclass(frozen=True)
class LocalMap:
    """A window of the memory around the robot: free cells (hits inflated by the robot radius)
    and the connected free region the robot is in."""

    row0: int  # window offset in the memory grid
    col0: int
    free: np.ndarray  # (h, w) bool
    reachable: np.ndarray  # (h, w) bool, the robot's connected component of ``free``
    memory: ObstacleMemory

    def lookup(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(rows, cols, inside)`` window cells of ``points (N, 2)``; ``inside (N,) bool``."""
        rc = self.memory.cells(points) - np.array([self.row0, self.col0])
        h, w = self.free.shape
        inside = (rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w)
        return np.clip(rc[:, 0], 0, h - 1), np.clip(rc[:, 1], 0, w - 1), inside

    def is_reachable(self, points: np.ndarray) -> np.ndarray:
        r, c, inside = self.lookup(points)
        reachable: np.ndarray = inside & self.reachable[r, c]
        return reachable


def local_map(memory: ObstacleMemory, position: np.ndarray, half_cells: int,
              inflation: float) -> LocalMap:
    """The ``(2 n + 1)``-cell square window (``n = half_cells``) centred on the cell of
    ``position``; hits are inflated by ``inflation`` [m] (cells whose centre is within
    ``inflation + res / 2`` of a hit cell's centre are blocked) and cells off the memory grid
    are blocked (the map ends there). The window always has the same size, so its graph can be
    reused (:class:`WindowGraph`)."""
    res = memory.resolution
    H, W = memory.shape
    rc = memory.cells(np.asarray(position, np.float64))[0]
    n = int(half_cells)
    side = 2 * n + 1
    r0, c0 = int(rc[0]) - n, int(rc[1]) - n
    # Hits just outside the window still block cells inside it: inflate a padded window.
    pad = int(math.ceil(inflation / res)) + 1
    hits = np.zeros((side + 2 * pad, side + 2 * pad), dtype=bool)
    on_map = np.zeros_like(hits)
    sr0, sr1 = max(r0 - pad, 0), min(r0 + side + pad, H)
    sc0, sc1 = max(c0 - pad, 0), min(c0 + side + pad, W)
    if sr0 < sr1 and sc0 < sc1:
        dst = (slice(sr0 - (r0 - pad), sr1 - (r0 - pad)), slice(sc0 - (c0 - pad),
                                                               sc1 - (c0 - pad)))
        hits[dst] = memory.hits[sr0:sr1, sc0:sc1]
        on_map[dst] = True
    if hits.any():
        free = ndimage.distance_transform_edt(~hits) * res > inflation + 0.5 * res
    else:
        free = np.ones_like(hits)
    free = (free & on_map)[pad:pad + side, pad:pad + side]
    return LocalMap(r0, c0, free, _reachable_from_centre(free), memory)


def without_discs(local: LocalMap, centres: np.ndarray, radii: np.ndarray) -> LocalMap:
    """``local`` with the cells whose centre lies within ``radii (J,)`` (plus half a cell) of
    ``centres (J, 2)`` [m] blocked too - teammates as obstacles, for paths round them."""
    mem = local.memory
    h, w = local.free.shape
    free = local.free.copy()
    centres = np.asarray(centres, np.float64).reshape(-1, 2)
    cells = mem.cells(centres) - np.array([local.row0, local.col0])
    reaches = np.asarray(radii, np.float64) + 0.5 * mem.resolution
    for centre, (r, c), reach in zip(centres, cells, reaches, strict=True):
        k = int(math.ceil(reach / mem.resolution)) + 1  # only the disc's box is looked at
        r0, r1, c0, c1 = max(r - k, 0), min(r + k + 1, h), max(c - k, 0), min(c + k + 1, w)
        if r0 >= r1 or c0 >= c1:
            continue  # off the window
        rows, cols = np.mgrid[r0:r1, c0:c1]
        xy = mem.centers(rows + local.row0, cols + local.col0)
        free[r0:r1, c0:c1] &= np.hypot(xy[..., 0] - centre[0], xy[..., 1] - centre[1]) > reach
    return LocalMap(local.row0, local.col0, free, _reachable_from_centre(free), mem)


def _reachable_from_centre(free: np.ndarray) -> np.ndarray:
    """The connected component of ``free`` that holds the window's centre cell (the robot)."""
    # 4-connected components: the graph's diagonals need both side cells free, so they connect
    # exactly what 4-neighbour steps connect.
    labels, _ = ndimage.label(free)
    reachable = np.zeros_like(free)
    rr = cc = free.shape[0] // 2
    if not free[rr, cc] and free.any():
        # The robot is inside the inflation (closer than its radius to a remembered hit, e.g.
        # a hit quantised to a cell): start from the nearest free cell.
        _, (ir, ic) = ndimage.distance_transform_edt(~free, return_indices=True)
        rr, cc = int(ir[rr, cc]), int(ic[rr, cc])
    if free[rr, cc]:
        reachable = labels == labels[rr, cc]
    return reachable


def local_maximum_goal(points: np.ndarray, values: np.ndarray, position: np.ndarray,
                       previous: np.ndarray | None = None, match_radius: float = 0.0
                       ) -> int | None:
    """Index of the goal among candidate ``points (N, 2)`` with density ``values (N,)``: the
    highest value, ties broken by distance to ``position``. The candidate nearest to the
    ``previous`` goal (if within ``match_radius`` [m] of it) is kept while its value is within
    :data:`GOAL_HYSTERESIS` of the best. None if there is no candidate."""
    if len(points) == 0:
        return None
    best = float(values.max())
    if previous is not None:
        near = np.hypot(*(points - np.asarray(previous, np.float64)).T)
        k = int(np.argmin(near))
        if near[k] <= match_radius and values[k] >= best * (1.0 - GOAL_HYSTERESIS):
            return k
    top = np.flatnonzero(values >= best * (1.0 - 1e-9))
    d = np.hypot(*(points[top] - np.asarray(position, np.float64)).T)
    return int(top[np.argmin(d)])


@dataclass(frozen=True)
class NavigationField:
    """Cost-to-go ``M_go`` [m] to a goal over a :class:`LocalMap` window (inf off the goal's
    free region)."""

    local: LocalMap
    cost: np.ndarray  # (h, w) [m]
    goal: np.ndarray  # (2,) [m]

    def at(self, points: np.ndarray) -> np.ndarray:
        """``(N,)`` [m] cost-to-go at ``points (N, 2)``, bilinear between the four surrounding
        cell centres when all four are finite (smooth for the centroid), else the containing
        cell's value; inf outside the window."""
        mem = self.local.memory
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        g = (pts - mem.origin) / mem.resolution - 0.5  # cell-centre coordinates
        g -= np.array([self.local.col0, self.local.row0])
        h, w = self.cost.shape
        c0 = np.clip(np.floor(g[:, 0]).astype(np.int64), 0, w - 1)
        r0 = np.clip(np.floor(g[:, 1]).astype(np.int64), 0, h - 1)
        c1, r1 = np.minimum(c0 + 1, w - 1), np.minimum(r0 + 1, h - 1)
        fx = np.clip(g[:, 0] - c0, 0.0, 1.0)
        fy = np.clip(g[:, 1] - r0, 0.0, 1.0)
        q00, q01 = self.cost[r0, c0], self.cost[r0, c1]
        q10, q11 = self.cost[r1, c0], self.cost[r1, c1]
        with np.errstate(invalid="ignore"):
            bilinear = ((1 - fy) * ((1 - fx) * q00 + fx * q01)
                        + fy * ((1 - fx) * q10 + fx * q11))
        r, c, inside = self.local.lookup(pts)
        own = self.cost[r, c]
        out = np.where(np.isfinite(bilinear), bilinear, own)
        return np.where(inside, out, np.inf)


class WindowGraph:
    """The 8-connected graph of a square window of ``side x side`` cells, built once: per
    update only the edge weights change (:meth:`csr`). A diagonal step needs both side cells
    free, so paths never cut a corner; a blocked edge gets weight :data:`BLOCKED_COST`."""

    #: (drow, dcol) of the four undirected edge directions; each is stored both ways.
    DIRECTIONS = ((0, 1), (1, 0), (1, 1), (1, -1))

    def __init__(self, side: int, resolution: float) -> None:
        ids = np.arange(side * side, dtype=np.int64).reshape(side, side)
        us, vs, lengths = [], [], []
        for dr, dc in self.DIRECTIONS:
            src, dst, _, _ = self._slices(side, dr, dc)
            a, b = ids[src].ravel(), ids[dst].ravel()
            us += [a, b]
            vs += [b, a]
            lengths += [np.full(2 * len(a), math.hypot(dr, dc) * resolution)]
        u, v = np.concatenate(us), np.concatenate(vs)
        self.order = np.lexsort((v, u))  # edge order of the CSR among the construction order
        self.side = side
        self.indices = v[self.order]
        self.length = np.concatenate(lengths)[self.order]
        self.indptr = np.zeros(side * side + 1, dtype=np.int64)
        np.cumsum(np.bincount(u, minlength=side * side), out=self.indptr[1:])

    @staticmethod
    def _slices(side: int, dr: int, dc: int) -> tuple[tuple[slice, slice], ...]:
        """Index windows of the edge sources, their ends and (diagonals) the two side cells."""
        c0, c1 = max(0, -dc), side - max(0, dc)
        src = (slice(0, side - dr), slice(c0, c1))
        dst = (slice(dr, side), slice(c0 + dc, c1 + dc))
        return src, dst, (dst[0], src[1]), (src[0], dst[1])

    def csr(self, free: np.ndarray) -> csr_matrix:
        """The ``(N, N)`` directed CSR for the window's ``free (side, side)`` mask."""
        f = np.asarray(free, dtype=bool)
        parts = []
        for dr, dc in self.DIRECTIONS:
            src, dst, side_a, side_b = self._slices(self.side, dr, dc)
            ok = f[src] & f[dst]
            if dr and dc:
                ok &= f[side_a] & f[side_b]
            parts += [ok.ravel(), ok.ravel()]
        ok = np.concatenate(parts)[self.order]
        n = self.side * self.side
        return csr_matrix((np.where(ok, self.length, BLOCKED_COST), self.indices, self.indptr),
                          shape=(n, n))


def navigation_function(local: LocalMap, goal: np.ndarray, graph: WindowGraph | None = None,
                        origin: np.ndarray | None = None, reach: float = 0.0) -> NavigationField:
    """Dijkstra backwards from ``goal`` over the window's free cells (Lemma 2: 0 at the goal,
    decreasing along every shortest path, inf where the goal cannot be reached). ``graph`` is
    the window's cached :class:`WindowGraph` (built if not given).

    With an ``origin`` (the robot), the search first stops at :data:`FIRST_LIMIT_FACTOR`
    ``* reach`` and is redone without limit only if the origin's cost plus ``reach`` [m] (the
    size of the robot's cell) exceeds that; costs are exact wherever they are below the limit,
    so exact on the whole cell."""
    side = local.free.shape[0]
    if graph is None or graph.side != side:
        graph = WindowGraph(side, local.memory.resolution)
    r, c, inside = local.lookup(np.asarray(goal, np.float64))
    cost = np.full(local.free.shape, np.inf)
    if inside[0] and local.free[r[0], c[0]]:
        node = int(r[0]) * side + int(c[0])
        csr = graph.csr(local.free)
        limit = FIRST_LIMIT_FACTOR * reach if origin is not None and reach > 0 else np.inf
        d = dijkstra(csr, directed=True, indices=node, limit=limit)
        if np.isfinite(limit):
            ro, co, ok = local.lookup(np.asarray(origin, np.float64))
            if not (ok[0] and d[int(ro[0]) * side + int(co[0])] + reach < limit):
                d = dijkstra(csr, directed=True, indices=node)
        cost = np.where(d < 0.5 * BLOCKED_COST, d, np.inf).reshape(local.free.shape)
    return NavigationField(local, cost, np.asarray(goal, np.float64).copy())


def guided_density(cost_to_go: np.ndarray, gamma: float) -> np.ndarray:
    """Eq. 8, ``phi = exp(-gamma M_go)`` for ``(N,)`` costs [m] (0 where inf). Scaled by
    ``exp(gamma min M_go)`` so the largest value is 1 - a constant factor that leaves every
    centroid unchanged but keeps far goals from underflowing."""
    m = np.asarray(cost_to_go, dtype=np.float64)
    finite = np.isfinite(m)
    out = np.zeros(m.shape)
    if finite.any():
        out[finite] = np.exp(-gamma * (m[finite] - m[finite].min()))
    return out
