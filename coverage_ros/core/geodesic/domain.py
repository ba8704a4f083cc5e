"""The coverage domain: where robots may be, how far apart places are, and what matters.

A :class:`CoverageDomain` bundles

* ``geometry`` - a :class:`GridMap` giving resolution, origin and cell <-> map conversions;
* ``graph`` - the metric :class:`GridGraph` over the configuration space (free cells inflated by
  the robot radius), whose shortest paths define the geodesic distance d_l;
* ``density`` - ``(H, W)`` importance w(q) >= 0 at cell centres (0 on blocked cells);
* optionally a metric: isotropic weight ``zeta`` ``(H, W)`` or tensor ``(H, W, 2, 2)``.

Continuous positions (robots are not on vertices) enter graph searches through a *virtual
source*: an extra node joined to the free cells around the point by edges of their metric
length, so distances are measured from the real position and vary smoothly with it.

Coordinates: map-frame points ``(x, y)`` [m]; internally *grid coordinates* ``(gx, gy)`` in
cells, with cell ``(row, col)`` centred at ``(col + 0.5, row + 0.5)``. Chart displacements are
grid displacements times the resolution, in grid axes (rotated by the grid's yaw from the map).
"""

from __future__ import annotations

import math
from collections.abc import Hashable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from coverage_ros.core.geodesic.graph import GridGraph, build_grid_graph
from coverage_ros.core.geodesic.sight import LineOfSight
from coverage_ros.core.world.density import Density, UniformDensity, density_on_grid
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError

#: [chart units] scale of the tie-breaking bias added to every edge out of a virtual source.
TIE_BIAS = 1e-9
#: A point's virtual-source connections ``(nodes, costs, grid_xy)`` (CoverageDomain.snap).
Snap = tuple[np.ndarray, np.ndarray, np.ndarray]


def tie_bias(grid_xy: np.ndarray) -> float:
    """A tiny distance offset that depends only on a source's position. Cells exactly as far
    from two robots (common when robots sit on cell centres) then go to the same robot in every
    robot's own search, in the centralized tessellation and in the references alike."""
    x, y = (float(v) for v in np.asarray(grid_xy, dtype=np.float64).ravel()[:2])
    h = math.sin(x * 12.9898 + y * 78.233) * 43758.5453
    return TIE_BIAS * (h - math.floor(h))


@dataclass(frozen=True, eq=False)
class CoverageDomain(LineOfSight):
    geometry: GridMap
    graph: GridGraph
    density: np.ndarray  # (H, W) float64 >= 0, zero on blocked cells
    tensor: np.ndarray | None = None  # (H, W, 2, 2) metric tensor in grid axes, or None
    zeta: np.ndarray | None = None  # (H, W) isotropic metric weight, or None
    robot_radius: float = 0.0  # [m] the free space is inflated by this (maps)
    unknown_is_free: bool = False  # unknown map cells count as free (exploration)
    #: the grid this one was cut from (:mod:`~coverage_ros.core.geodesic.crop`) and the
    #: (column, row) there of this one's first cell: points and tie biases are taken in its
    #: coordinates less the offset, so a cut domain computes as the whole one does
    cut_from: tuple[GridMap, tuple[int, int]] | None = None
    _cache: dict[Hashable, Any] = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_grid(cls, grid: GridMap, robot_radius: float, density: Density | None = None,
                  connectivity: int = 8, unknown_is_free: bool = False,
                  zeta: np.ndarray | None = None) -> CoverageDomain:
        """Domain of a disc robot of ``robot_radius`` [m] on an occupancy grid."""
        free = grid.inflated_free_mask(robot_radius, unknown_is_free=unknown_is_free)
        graph = build_grid_graph(free, grid.resolution, connectivity=connectivity, zeta=zeta)
        w = density_on_grid(density or UniformDensity(), grid, free)
        return cls(geometry=grid, graph=graph, density=w, zeta=zeta, robot_radius=robot_radius,
                   unknown_is_free=unknown_is_free)

    @property
    def clearance(self) -> np.ndarray:
        """``(H, W)`` [m] distance of every cell centre to the nearest obstacle cell."""
        key = "clearance"
        if key not in self._cache:
            self._cache[key] = self.geometry.clearance(unknown_is_free=self.unknown_is_free)
        clearance: np.ndarray = self._cache[key]
        return clearance

    def margin_free(self, margin: float) -> np.ndarray:
        """``(H, W) bool``: free cells at least ``margin`` [m] farther from obstacles than the
        configuration space requires (where planned shortcuts may run); memoized."""
        key = ("margin_free", float(margin))
        if key not in self._cache:
            need = self.robot_radius + 0.5 * self.resolution + margin
            self._cache[key] = self.free & (self.clearance >= need)
        free: np.ndarray = self._cache[key]
        return free

    # ------------------------------------------------------------------ basic properties
    @property
    def shape(self) -> tuple[int, int]:
        return self.graph.shape

    @property
    def resolution(self) -> float:
        return self.geometry.resolution

    @property
    def free(self) -> np.ndarray:
        return self.graph.free

    @property
    def mass_element(self) -> np.ndarray:
        """``(H, W)``: w(q) * dA(q), the weight of each cell in integrals."""
        key = "mass_element"
        if key not in self._cache:
            self._cache[key] = self.density * self.graph.cell_area()
        mass: np.ndarray = self._cache[key]
        return mass

    def area_of(self, nodes: np.ndarray) -> float:
        """[m^2] the area of the cells ``nodes`` (by the area element on a curved chart)."""
        area = self.graph.area
        return len(nodes) * self.resolution ** 2 if area is None else float(
            area.ravel()[nodes].sum())

    def with_density(self, density: np.ndarray) -> CoverageDomain:
        """Same geometry and metric, another density raster (zeroed off the free space)."""
        w = np.asarray(density, dtype=np.float64)
        if w.shape != self.shape or np.any(w < 0) or not np.all(np.isfinite(w)):
            raise ConfigError.at("density", "must be a finite (H, W) array >= 0", w.shape)
        return CoverageDomain(self.geometry, self.graph, np.where(self.free, w, 0.0),
                              self.tensor, self.zeta, self.robot_radius, self.unknown_is_free,
                              self.cut_from)

    @property
    def metric_lower_bound(self) -> float:
        """lambda with d_l(x, y) >= lambda * |x - y| (chart units): the square root of the
        smallest eigenvalue of the metric over the free cells (1 for maps)."""
        key = "lower_bound"
        if key not in self._cache:
            if self.tensor is not None:
                eig = np.linalg.eigvalsh(self.tensor[self.free])
                value = float(np.sqrt(eig.min())) if eig.size else 1.0
            elif self.zeta is not None:
                z = self.zeta[self.free]
                value = float(np.sqrt(z.min())) if z.size else 1.0
            else:
                value = 1.0
            self._cache[key] = value
        bound: float = self._cache[key]
        return bound

    def bias(self, grid_xy: np.ndarray) -> float:
        """:func:`tie_bias` of a source at ``grid_xy`` [cells], taken in the grid this one was
        cut from."""
        off = (0, 0) if self.cut_from is None else self.cut_from[1]
        return tie_bias(np.asarray(grid_xy, dtype=np.float64).ravel()[:2] + off)

    # ------------------------------------------------------------------ coordinates
    def to_grid(self, points: np.ndarray) -> np.ndarray:
        """Map-frame ``(N, 2)`` [m] -> grid coordinates ``(N, 2)`` [cells]."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if self.cut_from is None:
            return self.geometry.world_to_grid(pts)
        return self.cut_from[0].world_to_grid(pts) - self.cut_from[1]  # (whole cells: exact)

    def to_map(self, grid_xy: np.ndarray) -> np.ndarray:
        g = np.asarray(grid_xy, dtype=np.float64).reshape(-1, 2)
        frame, off = self.cut_from or (self.geometry, (0, 0))
        return frame.grid_to_world(g + off)

    def grid_vector_to_map(self, v: np.ndarray) -> np.ndarray:
        """Rotate chart/grid-axis vectors ``(..., 2)`` into the map frame."""
        c, s = math.cos(self.geometry.origin[2]), math.sin(self.geometry.origin[2])
        v = np.asarray(v, dtype=np.float64)
        return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)

    def node_centers(self, nodes: np.ndarray) -> np.ndarray:
        """Grid coordinates ``(N, 2)`` of node centres."""
        W = self.shape[1]
        nodes = np.asarray(nodes, dtype=np.int64)
        return np.stack([nodes % W + 0.5, nodes // W + 0.5], axis=-1)

    def metric_at(self, grid_xy: np.ndarray) -> np.ndarray:
        """``(N, 2, 2)`` metric tensor (chart units) at grid points (identity for maps)."""
        pts = np.asarray(grid_xy, dtype=np.float64).reshape(-1, 2)
        eye = np.broadcast_to(np.eye(2), (len(pts), 2, 2)).copy()
        if self.tensor is None and self.zeta is None:
            return eye
        cells = self._clamped_cells(pts)
        if self.tensor is not None:
            tensors: np.ndarray = self.tensor[cells[:, 0], cells[:, 1]].copy()
            return tensors
        assert self.zeta is not None
        scaled: np.ndarray = eye * self.zeta[cells[:, 0], cells[:, 1]][:, None, None]
        return scaled

    def _clamped_cells(self, grid_xy: np.ndarray) -> np.ndarray:
        H, W = self.shape
        col = np.floor(grid_xy[:, 0]).astype(np.int64)
        row = np.floor(grid_xy[:, 1]).astype(np.int64)
        col = col % W if self.graph.wrap[1] else np.clip(col, 0, W - 1)
        row = row % H if self.graph.wrap[0] else np.clip(row, 0, H - 1)
        return np.stack([row, col], axis=-1)

    def chart_displacement(self, frm: np.ndarray, to: np.ndarray) -> np.ndarray:
        """``to - frm`` in chart units (grid axes), wrapped to the shortest image on charts
        that wrap around."""
        d = (np.asarray(to, dtype=np.float64) - np.asarray(frm, dtype=np.float64))
        H, W = self.shape
        if self.graph.wrap[1]:
            d[..., 0] = (d[..., 0] + 0.5 * W) % W - 0.5 * W
        if self.graph.wrap[0]:
            d[..., 1] = (d[..., 1] + 0.5 * H) % H - 0.5 * H
        return d * self.resolution

    # ------------------------------------------------------------------ free space queries
    @property
    def nearest_free_index(self) -> np.ndarray:
        """``(2, H, W)``: for every cell, the (row, col) of the nearest free cell."""
        key = "nearest_free"
        if key not in self._cache:
            if not self.free.any():
                raise ConfigError("domain: no free cell (is the robot radius larger than every "
                                  "passage?)")
            from scipy import ndimage  # scipy's import is a tenth of a second: only when used

            _, idx = ndimage.distance_transform_edt(~self.free, return_indices=True)
            self._cache[key] = idx
        nearest: np.ndarray = self._cache[key]
        return nearest

    def snap(self, point_map: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Virtual-source connections of one map-frame point.

        Returns ``(nodes, costs, grid_xy)``: the free nodes the point connects to (the cell
        containing it first), the metric lengths of those connections, and the point in grid
        coordinates. A point on a free cell
        connects to that cell and to those of the 2x2 surrounding cell centres that share a
        graph edge with it; a point on a blocked cell connects to the nearest free cell.
        """
        g = self.to_grid(point_map)[0]
        H, W = self.shape
        cell = self._clamped_cells(g[None])[0]
        r, c = int(cell[0]), int(cell[1])
        inside = (0 <= math.floor(g[1]) < H or self.graph.wrap[0]) and (
            0 <= math.floor(g[0]) < W or self.graph.wrap[1])
        if inside and self.free[r, c]:
            nodes = [r * W + c]
            # Neighbour cells of the 2x2 block of centres around the point.
            dc = 1 if g[0] - c >= 0.5 else -1
            dr = 1 if g[1] - r >= 0.5 else -1
            for odr, odc in ((0, dc), (dr, 0), (dr, dc)):
                k = self._offset_index(odr, odc)
                if k is not None and np.isfinite(self.graph.cost[r, c, k]):
                    nodes.append(int(self.graph.neighbour_index(k)[r, c]))
            nodes_arr = np.array(list(dict.fromkeys(nodes)), dtype=np.int64)  # own cell first
        else:
            idx = self.nearest_free_index
            rr, cc = int(idx[0, r, c]), int(idx[1, r, c])
            nodes_arr = np.array([rr * W + cc], dtype=np.int64)
        centers = self.node_centers(nodes_arr)
        disp = self.chart_displacement(g[None], centers)
        metric = self.metric_at(g[None])[0]
        costs = np.sqrt(np.einsum("ni,ij,nj->n", disp, metric, disp))
        return nodes_arr, costs + self.bias(g), g

    def free_at_grid(self, g: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rows, columns and free flags (False outside the grid) of the cells containing the
        ``(N, 2)`` grid points ``g`` (x = column, y = row, in cells)."""
        H, W = self.shape
        c = np.floor(g[:, 0]).astype(np.int64)
        r = np.floor(g[:, 1]).astype(np.int64)
        inside = (r >= 0) & (r < H) & (c >= 0) & (c < W)
        ok = inside.copy()
        ok[inside] = self.free[r[inside], c[inside]]
        return r, c, ok

    def snap_many(self, points_map: np.ndarray) -> list[Snap]:
        """:meth:`snap` for ``(N, 2)`` points; vectorized for maps (Euclidean, no wrap)."""
        pts = np.asarray(points_map, dtype=np.float64).reshape(-1, 2)
        if not self.graph.euclidean or any(self.graph.wrap) or len(pts) == 0:
            return [self.snap(p) for p in pts]
        g = self.to_grid(pts)
        W = self.shape[1]
        r, c, ok = self.free_at_grid(g)
        dc = np.where(g[:, 0] - c >= 0.5, 1, -1)
        dr = np.where(g[:, 1] - r >= 0.5, 1, -1)
        # Own cell, then the cells across the nearer column edge, row edge and corner.
        odr = np.stack([np.zeros_like(dr), np.zeros_like(dr), dr, dr], axis=1)
        odc = np.stack([np.zeros_like(dc), dc, np.zeros_like(dc), dc], axis=1)
        base = np.where(ok, r * W + c, 0)
        nodes = base[:, None] + odr * W + odc
        has = np.zeros(nodes.shape, dtype=bool)
        has[:, 0] = True
        bits = self.graph.edge_bits[base]
        for j in range(1, 4):
            k = self._offset_indices(odr[:, j], odc[:, j])
            has[:, j] = (k >= 0) & ((bits >> np.maximum(k, 0)) & 1).astype(bool)
        centers = np.stack([nodes % W + 0.5, nodes // W + 0.5], axis=-1)
        costs = np.hypot(*(centers - g[:, None, :]).transpose(2, 0, 1)) * self.resolution
        out = []
        for i in range(len(pts)):
            if not ok[i]:
                out.append(self.snap(pts[i]))
                continue
            keep = has[i]
            out.append((nodes[i, keep], costs[i, keep] + self.bias(g[i]), g[i]))
        return out

    def seeds(self, point_map: np.ndarray, nodes: np.ndarray, centers: np.ndarray,
              radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Virtual-source edges of a point: its :meth:`snap` connections, plus (when
        :attr:`sees_straight`) every cell among ``nodes`` (grid centres ``centers``) within
        ``radius`` chart units and in line of sight, at its straight-line distance.

        Returns ``(nodes, costs, grid_xy)`` like :meth:`snap`.
        """
        snap_nodes, snap_costs, g = self.snap(point_map)
        if not self.sees_straight or len(nodes) == 0:
            return snap_nodes, snap_costs, g
        r_cells = radius / self.resolution
        d2 = (centers[:, 0] - g[0]) ** 2 + (centers[:, 1] - g[1]) ** 2
        near = np.flatnonzero(d2 <= r_cells * r_cells)
        reach = math.sqrt(float(d2[near].max())) if len(near) else 0.0
        vis = near[self.visible_mask(g, centers[near], reach)]
        all_nodes = np.concatenate([snap_nodes, nodes[vis]])
        all_costs = np.concatenate([snap_costs,
                                    np.sqrt(d2[vis]) * self.resolution + self.bias(g)])
        return all_nodes, all_costs, g

    def _offset_index(self, dr: int, dc: int) -> int | None:
        key = ("offset", dr, dc)
        if key not in self._cache:
            hits = np.flatnonzero((self.graph.offsets[:, 0] == dr)
                                  & (self.graph.offsets[:, 1] == dc))
            self._cache[key] = int(hits[0]) if hits.size else None
        index: int | None = self._cache[key]
        return index

    def _offset_indices(self, dr: np.ndarray, dc: np.ndarray) -> np.ndarray:
        """:meth:`_offset_index` for arrays of offsets in -1..1; -1 where the graph has none."""
        key = "offset_table"
        if key not in self._cache:
            table = np.full((3, 3), -1, dtype=np.int64)
            for a in (-1, 0, 1):
                for b in (-1, 0, 1):
                    k = self._offset_index(a, b)
                    table[a + 1, b + 1] = -1 if k is None else k
            self._cache[key] = table
        indices: np.ndarray = self._cache[key][np.asarray(dr) + 1, np.asarray(dc) + 1]
        return indices

    def is_free_point(self, point_map: np.ndarray) -> bool:
        g = self.to_grid(point_map)[0]
        H, W = self.shape
        r, c = math.floor(g[1]), math.floor(g[0])
        if not (self.graph.wrap[0] or 0 <= r < H) or not (self.graph.wrap[1] or 0 <= c < W):
            return False
        return bool(self.free[r % H, c % W])
