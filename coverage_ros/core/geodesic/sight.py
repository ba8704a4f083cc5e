"""Line of sight on a coverage domain: which blocked cells can hide anything, the polar depth
maps made from them, and the tests of points against those maps (one by one, or a tile of
cells at a time when many are asked). :class:`LineOfSight` is a part of
:class:`~coverage_ros.core.geodesic.domain.CoverageDomain`, kept in a room of its own."""

from __future__ import annotations

import math
from collections import OrderedDict
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
#: [cells] An occluder can hide a point from an origin only within this distance of the segment
#: between them, along each axis, plus the width of an angular bin at the point: its disc (half a
#: cell diagonal, which seen from up close spans up to a quarter turn) reaching into the point's
#: bin, with a cell to spare.
SEGMENT_MARGIN = 2.2
#: The depth maps a caller keeps, by origin: ``[box, depth map, tile states or None]``.
DepthMaps = dict[tuple[float, float], list[Any]]
#: [bytes] depth maps a domain keeps between searches (:meth:`LineOfSight.kept_depth_maps`)
KEPT_DEPTH_BYTES = 8 << 20


class KeptDepthMaps(OrderedDict[tuple[float, float], list[Any]]):
    """Depth maps by origin, at most ``capacity`` of them, the least recently used dropped
    first (a :data:`DepthMaps` kept between calls)."""

    def __init__(self, capacity: int = 16) -> None:  # (a default: copies are made empty)
        super().__init__()
        self.capacity = capacity

    def get(self, key: tuple[float, float], default: Any = None) -> Any:
        held = super().get(key)
        if held is None:
            return default
        self.move_to_end(key)
        return held

    def __setitem__(self, key: tuple[float, float], held: list[Any]) -> None:
        super().__setitem__(key, held)
        self.move_to_end(key)
        while len(self) > self.capacity:
            self.popitem(last=False)


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
        side of the grid. A domain cut from a larger one keeps the larger one's, set in its
        cache (:func:`~coverage_ros.core.geodesic.crop.cropped`): the same answers."""
        kept: int | None = self._cache.get("depth_bins")
        if kept is not None:
            return kept
        H, W = self.shape
        bins: int = 2 ** math.ceil(math.log2(2.0 * math.pi * math.hypot(H, W)))
        return min(max(bins, 1024), 16384)

    @property
    def free_rectangle(self) -> tuple[float, float, float, float] | None:
        """``(x0, y0, x1, y1)`` [cells, grid coordinates]: the rectangle the free cells fill
        when they fill their bounding box (an open field inside its walls), else None. Every
        segment between two of its points stays in it, so nothing hides a free cell from a
        point in it."""
        key = "free_rectangle"
        if key not in self._cache:
            rows, cols = np.nonzero(self.free)
            box = None
            if len(rows) and self.free[rows.min():rows.max() + 1,
                                       cols.min():cols.max() + 1].all():
                box = (float(cols.min()), float(rows.min()), float(cols.max() + 1),
                       float(rows.max() + 1))
            self._cache[key] = box
        rectangle: tuple[float, float, float, float] | None = self._cache[key]
        return rectangle

    @property
    def occluder_centers(self) -> np.ndarray:
        """``(M, 2)`` grid coordinates of the :attr:`occluders`' centres (x = column + 0.5)."""
        key = "occluder_centers"
        if key not in self._cache:
            rr, cc = np.nonzero(self.occluders)
            self._cache[key] = np.stack([cc + 0.5, rr + 0.5], axis=-1).astype(np.float64)
        centers: np.ndarray = self._cache[key]
        return centers

    def kept_depth_maps(self) -> DepthMaps:
        """The domain's own :data:`DepthMaps`, kept between searches (made on first use; at
        most :data:`KEPT_DEPTH_BYTES` of maps): a map depends on its origin and the domain
        alone, and one of a larger box changes no answer (:meth:`_depth_map`), so searches
        from a generator that stands where one stood before (a descent's start, again for
        every move it prices) make none anew."""
        kept = self._cache.get("kept_depth_maps")
        if kept is None:
            kept = KeptDepthMaps(max(16, KEPT_DEPTH_BYTES // (8 * self.depth_bins)))
            self._cache["kept_depth_maps"] = kept
        maps: DepthMaps = kept
        return maps

    def visible_mask(self, origin: np.ndarray, points: np.ndarray, radius: float,
                     depths: DepthMaps | None = None,
                     point_tiles: np.ndarray | None = None) -> np.ndarray:
        """``(N,) bool``: grid points (within ``radius`` cells of the grid point ``origin``)
        in line of sight of it; blocked cells are discs of half a cell diagonal.

        ``depths``, a dict the caller keeps, holds the depth maps made so far by origin, each
        of the occluders in a box: one whose box holds the radius' is used again. That
        changes no answer (:meth:`_depth_map`). With ``depths``, many points are first
        decided a tile at a time (:meth:`sight_tiles`; same answers); ``point_tiles``, the
        points' :func:`~coverage_ros.core.geodesic.tangents.tile_index` when the caller has
        them, saves working them out."""
        held = self._depth_map(origin, self._around(origin, radius), depths)
        if held is None:
            return np.ones(len(points), dtype=bool)
        if depths is None or len(points) < TILED_FROM:
            return visible_from(origin, points, held[1])
        if point_tiles is None:
            point_tiles = tile_index(points, self.shape)
        return visible_from(origin, points, held[1],
                            (self.sight_tiles(origin, radius, depths), point_tiles))

    def visible_each(self, origin: np.ndarray, points: np.ndarray,
                     depths: DepthMaps) -> np.ndarray:
        """:meth:`visible_mask` of ``points (N, 2)`` anywhere, point by point, from a depth
        map of the occluders around the segments from ``origin`` to them only (kept in
        ``depths``)."""
        if len(points) == 0:
            return np.zeros(0, dtype=bool)
        held = self._depth_map(origin, self._spanning(origin, points), depths)
        return np.ones(len(points), dtype=bool) if held is None else visible_from(
            origin, points, held[1])

    def sight_tiles(self, origin: np.ndarray, radius: float, depths: DepthMaps) -> np.ndarray:
        """:func:`~coverage_ros.core.geodesic.tangents.sight_tiles` of the depth map that
        :meth:`visible_mask` uses for ``origin`` and ``radius`` (made once, kept in
        ``depths``): per tile, 1 seen whole, 0 hidden whole, -1 to be tested point by point;
        all 1 when no occluder lies within the radius' box. Only the answers for tiles within
        the radius are the whole domain's."""
        held = self._depth_map(origin, self._around(origin, radius), depths)
        if held is None:
            H, W = self.shape
            return np.ones(-(-H // SIGHT_TILE) * -(-W // SIGHT_TILE), dtype=np.int8)
        if held[2] is None:
            held[2] = sight_tiles(origin, held[1], self.shape)
        tiles: np.ndarray = held[2]
        return tiles

    def sight_tiles_whole(self, origin: np.ndarray, depths: DepthMaps) -> np.ndarray:
        """:meth:`sight_tiles` of every tile of the domain from ``origin``, from one depth map
        of every occluder (kept in ``depths``, with the answers): what a whole-map search
        reads for each generator."""
        H, W = self.shape
        return self.sight_tiles(origin, math.hypot(H, W), depths)

    def _around(self, origin: np.ndarray, radius: float) -> tuple[float, ...]:
        """The box ``(x0, y0, x1, y1)`` [cells] of occluders that can hide a point within
        ``radius`` cells of ``origin``."""
        R = radius + 3.0  # (an occluder farther is farther than its disc reaches: > radius)
        return self._clip((origin[0] - R, origin[1] - R, origin[0] + R, origin[1] + R))

    def _spanning(self, origin: np.ndarray, points: np.ndarray) -> tuple[float, ...]:
        """The box of occluders that can hide one of ``points`` from ``origin``: around the
        segments between them (:data:`SEGMENT_MARGIN`)."""
        H, W = self.shape
        margin = SEGMENT_MARGIN + 2.0 * math.pi * math.hypot(H, W) / self.depth_bins
        xs, ys = points[:, 0], points[:, 1]  # (column by column: a reduction along the
        # short axis of an (N, 2) array is many times slower)
        return self._clip((min(float(xs.min()), float(origin[0])) - margin,
                           min(float(ys.min()), float(origin[1])) - margin,
                           max(float(xs.max()), float(origin[0])) + margin,
                           max(float(ys.max()), float(origin[1])) + margin))

    def _clip(self, box: tuple[float, float, float, float]) -> tuple[float, ...]:
        """``box`` within the grid (give or take a cell: every occluder lies inside)."""
        H, W = self.shape
        return (max(box[0], -1.0), max(box[1], -1.0), min(box[2], W + 1.0),
                min(box[3], H + 1.0))

    def _depth_map(self, origin: np.ndarray, box: tuple[float, ...], depths: DepthMaps | None
                   ) -> list[Any] | None:
        """``[box, depth map, tile states or None]`` of the occluders in ``box`` for
        ``origin`` (kept in ``depths``), or None when the box holds no occluder or the origin
        lies in the :attr:`free_rectangle` (the points asked about are free cells). The answer
        for a point is the whole domain's when the box holds the segment from ``origin`` to
        it widened by :data:`SEGMENT_MARGIN`: only an occluder whose disc reaches into the
        point's angular bin nearer than the point can hide it, and the bins are narrower
        than a cell at the far side of the grid. A kept map whose box holds ``box`` serves;
        one that does not grows by the occluders outside its box to the box around both (a
        depth is the least over occluders: the same map as made anew)."""
        rect = self.free_rectangle
        if rect is not None and rect[0] <= origin[0] <= rect[2] and \
                rect[1] <= origin[1] <= rect[3]:
            return None  # (a free cell is seen from anywhere in the free rectangle)
        key = (float(origin[0]), float(origin[1]))
        held = depths.get(key) if depths is not None else None
        if held is not None:
            old = held[0]
            if old[0] <= box[0] and old[1] <= box[1] and old[2] >= box[2] and old[3] >= box[3]:
                return held
            box = (min(old[0], box[0]), min(old[1], box[1]), max(old[2], box[2]),
                   max(old[3], box[3]))
        occ = self.occluder_centers
        occ = occ[_inside(occ, box)]
        if held is not None:  # (those of the kept map's box it has already)
            occ = occ[~_inside(occ, held[0])]
        if held is None and len(occ) == 0:
            return None
        depth = polar_depth(origin, occ, self.depth_bins)
        if held is not None:
            depth = np.minimum(held[1], depth)
        held = [box, depth, None]
        if depths is not None:
            depths[key] = held
        return held


def _inside(points: np.ndarray, box: tuple[float, ...]) -> np.ndarray:
    """``(N,) bool``: the points (grid coordinates) in ``box`` ``(x0, y0, x1, y1)``."""
    inside: np.ndarray = ((points[:, 0] >= box[0]) & (points[:, 0] <= box[2])
                          & (points[:, 1] >= box[1]) & (points[:, 1] <= box[3]))
    return inside
