"""Line of sight on a coverage domain: which blocked cells can hide anything, the polar depth
maps made from them, and the tests of points against those maps (one by one, or a tile of
cells at a time when many are asked). :class:`LineOfSight` is a part of
:class:`~coverage_ros.core.geodesic.domain.CoverageDomain`, kept in a room of its own."""

from __future__ import annotations

import math
from collections.abc import Hashable
from typing import TYPE_CHECKING, Any

import numpy as np

from coverage_ros.core.geodesic.graph import GridGraph
from coverage_ros.core.geodesic.tangents import (
    SIGHT_TILE,
    polar_depth,
    sight_tiles,
    tile_index,
    visible_from,
)

#: points from which :meth:`LineOfSight.visible_mask` decides line of sight by tiles first
TILED_FROM = 2048
#: The depth maps a caller keeps, by origin: ``[radius, depth map, tile states or None]``.
DepthMaps = dict[tuple[float, float], list[Any]]


class LineOfSight:
    """Line-of-sight queries of a domain (needs ``free``, ``shape``, ``graph`` and a
    ``_cache`` dict from the class it is part of)."""

    graph: GridGraph
    _cache: dict[Hashable, Any]
    if TYPE_CHECKING:
        @property
        def free(self) -> np.ndarray: ...

        @property
        def shape(self) -> tuple[int, int]: ...

    @property
    def sees_straight(self) -> bool:
        """Whether straight chart segments are geodesics (Euclidean metric, no wrap), so that
        sources may be joined to every cell in line of sight."""
        return self.graph.euclidean and not any(self.graph.wrap)

    @property
    def occluders(self) -> np.ndarray:
        """``(H, W) bool``: blocked cells next to a free one (the only ones that can block a
        line of sight between free cells)."""
        key = "occluders"
        if key not in self._cache:
            blocked = ~self.free
            from scipy import ndimage  # scipy's import is a tenth of a second: only when used

            near_free = ndimage.binary_dilation(self.free, structure=np.ones((3, 3), bool))
            self._cache[key] = blocked & near_free
        occluders: np.ndarray = self._cache[key]
        return occluders

    @property
    def depth_bins(self) -> int:
        """Angular bins of every line-of-sight depth map on this domain (fixed per domain, so
        that every computation of "visible" agrees): enough to resolve one cell at the far
        side of the grid."""
        H, W = self.shape
        return int(np.clip(2 ** math.ceil(math.log2(2.0 * math.pi * math.hypot(H, W))),
                           1024, 16384))

    @property
    def occluder_centers(self) -> np.ndarray:
        """``(M, 2)`` grid coordinates of the :attr:`occluders`' centres (x = column + 0.5)."""
        key = "occluder_centers"
        if key not in self._cache:
            rr, cc = np.nonzero(self.occluders)
            self._cache[key] = np.stack([cc + 0.5, rr + 0.5], axis=-1).astype(np.float64)
        centers: np.ndarray = self._cache[key]
        return centers

    def visible_mask(self, origin: np.ndarray, points: np.ndarray, radius: float,
                     depths: DepthMaps | None = None,
                     point_tiles: np.ndarray | None = None, by_tiles: bool = True
                     ) -> np.ndarray:
        """``(N,) bool``: grid points (within ``radius`` cells of the grid point ``origin``)
        in line of sight of it; blocked cells are discs of half a cell diagonal.

        ``depths``, a dict the caller keeps, holds the depth maps made so far by origin: one
        made for a radius at least as large is used again. That changes no answer - an
        occluder outside a radius' box is farther than any point the radius allows, so it
        cannot hide one. With ``depths``, many points are first decided a tile at a time
        (:meth:`sight_tiles`; same answers); ``point_tiles``, the points'
        :func:`~coverage_ros.core.geodesic.tangents.tile_index` when the caller has them,
        saves working them out; ``by_tiles`` False: point by point all the same (for points a
        caller knows no tile decides whole)."""
        held = self._depth_map(origin, radius, depths)
        if held is None:
            return np.ones(len(points), dtype=bool)
        if depths is None or len(points) < TILED_FROM or not by_tiles:
            return visible_from(origin, points, held[1])
        if point_tiles is None:
            point_tiles = tile_index(points, self.shape)
        return visible_from(origin, points, held[1],
                            (self.sight_tiles(origin, radius, depths), point_tiles))

    def sight_tiles(self, origin: np.ndarray, radius: float, depths: DepthMaps) -> np.ndarray:
        """:func:`~coverage_ros.core.geodesic.tangents.sight_tiles` of the depth map that
        :meth:`visible_mask` uses for ``origin`` and ``radius`` (made once, kept in
        ``depths``): per tile, 1 seen whole, 0 hidden whole, -1 to be tested point by point;
        all 1 when no occluder lies within the radius' box."""
        held = self._depth_map(origin, radius, depths)
        if held is None:
            H, W = self.shape
            return np.ones(-(-H // SIGHT_TILE) * -(-W // SIGHT_TILE), dtype=np.int8)
        if held[2] is None:
            held[2] = sight_tiles(origin, held[1], self.shape)
        tiles: np.ndarray = held[2]
        return tiles

    def sight_tiles_in(self, origin: np.ndarray, radius: float, depths: DepthMaps,
                       ids: np.ndarray) -> np.ndarray:
        """:meth:`sight_tiles` of the tiles ``ids`` (flat row-major indices), which must lie
        within ``radius`` cells of ``origin``: from a depth map of that radius (kept in
        ``depths``; the tile answers are not)."""
        held = self._depth_map(origin, radius, depths)
        if held is None:
            return np.ones(len(ids), dtype=np.int8)
        return sight_tiles(origin, held[1], self.shape, ids=ids)

    def _depth_map(self, origin: np.ndarray, radius: float, depths: DepthMaps | None
                   ) -> list[Any] | None:
        """``[radius, depth map, tile states or None]`` for ``origin`` (kept in ``depths``),
        or None when no occluder lies within the radius' box. A kept map of a smaller radius
        grows by the occluders outside its box only (a depth is the least over occluders:
        the same map as made anew)."""
        key = (float(origin[0]), float(origin[1]))
        held = depths.get(key) if depths is not None else None
        if held is not None and held[0] >= radius:
            return held
        occ = self._occluders_within(self.occluder_centers, origin, radius)
        if held is not None:  # (those of the kept map's box it has already)
            occ = occ[~self._occluders_within(occ, origin, held[0], mask=True)]
        if held is None and len(occ) == 0:
            return None
        depth = polar_depth(origin, occ, self.depth_bins)
        if held is not None:
            depth = np.minimum(held[1], depth)
        held = [radius, depth, None]
        if depths is not None:
            depths[key] = held
        return held

    def _occluders_within(self, occ: np.ndarray, origin: np.ndarray, radius: float,
                          mask: bool = False) -> np.ndarray:
        """The occluders of ``occ`` that can hide a point within ``radius`` cells of
        ``origin``: those in a box around it (all of them when the box holds the domain);
        ``mask``: which ones, as a boolean array."""
        R = radius + 2.0
        if R >= max(self.shape):
            return np.ones(len(occ), dtype=bool) if mask else occ
        inside: np.ndarray = ((np.abs(occ[:, 0] - origin[0]) <= R + 1.0)
                              & (np.abs(occ[:, 1] - origin[1]) <= R + 1.0))
        return inside if mask else occ[inside]
