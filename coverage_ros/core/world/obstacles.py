"""A world's static obstacles (:class:`Obstacle`): boxes, polygons and walls as polygons, and
circles."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coverage_ros.core.geometry import distance_to_segments, points_in_polygon, polygon_edges


@dataclass(frozen=True)
class Obstacle:
    """A static obstacle: a polygon (boxes and walls become polygons) or a circle."""

    kind: str  # "box" | "polygon" | "wall" | "circle"
    polygon: np.ndarray | None = None  # (M, 2) [m], counter-clockwise or not
    center: np.ndarray | None = None  # (2,) [m] circles only
    radius: float = 0.0  # [m] circles only

    def bounding_box(self) -> tuple[float, float, float, float]:
        if self.polygon is not None:
            lo, hi = self.polygon.min(axis=0), self.polygon.max(axis=0)
            return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])
        assert self.center is not None
        c, r = self.center, self.radius
        return float(c[0] - r), float(c[1] - r), float(c[0] + r), float(c[1] + r)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """``(N,)`` [m] distance from points to the obstacle (0 inside)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if self.polygon is not None:
            a, b = polygon_edges(self.polygon)
            d = distance_to_segments(pts, a, b)
            return np.where(points_in_polygon(pts, self.polygon), 0.0, d)
        assert self.center is not None
        outside: np.ndarray = np.maximum(np.hypot(*(pts - self.center).T) - self.radius, 0.0)
        return outside
