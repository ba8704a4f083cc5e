"""A region of interest set at run time: the importance density is kept inside a union of
polygons and set to zero outside, so the team re-spreads over the region (README "Using it on
your robots"). No polygons = the whole map.

A polygon comes from a user (``coverage-team --region``, a ``PolygonStamped`` from RViz clicks),
so it is checked before use: at least three finite points in the map frame, a non-zero area, and
some free space of the map inside the region.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from coverage_ros.core.geometry import polygon_area
from coverage_ros.core.world.density import TargetPolygons
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError


def checked_polygon(points: Any, where: str = "region") -> np.ndarray:
    """``(N, 2)`` float64 polygon from ``points``; ConfigError naming what is wrong."""
    try:
        poly = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    except (TypeError, ValueError):
        raise ConfigError.at(where, "must be a list of [x, y] points", points) from None
    if len(poly) < 3:
        raise ConfigError.at(where, "needs at least 3 points", len(poly))
    if not np.all(np.isfinite(poly)):
        raise ConfigError.at(where, "has a coordinate that is not a finite number",
                             poly.tolist())
    if not abs(polygon_area(poly)) > 1e-9:
        raise ConfigError.at(where, "has no area (its points are on one line)", poly.tolist())
    return poly


def parse_region_text(text: str, where: str = "--region") -> np.ndarray:
    """``"x,y;x,y;x,y"`` -> ``(N, 2)`` polygon."""
    try:
        pts = [[float(v) for v in p.split(",")] for p in text.split(";") if p.strip()]
    except ValueError:
        raise ConfigError.at(where, "must be 'x,y;x,y;...' [m]", text) from None
    if any(len(p) != 2 for p in pts):
        raise ConfigError.at(where, "must be 'x,y;x,y;...' [m] (two numbers per point)", text)
    return checked_polygon(pts, where)


@dataclass(frozen=True)
class Region:
    """A union of polygons (map frame); empty = everywhere."""

    polygons: tuple[np.ndarray, ...] = ()

    def with_polygon(self, polygon: Any) -> Region:
        return Region((*self.polygons, checked_polygon(polygon)))

    @property
    def everywhere(self) -> bool:
        return not self.polygons

    def holds(self, polygon: Any, tolerance: float = 0.0) -> bool:
        """Whether one of the polygons is ``polygon`` (``(M, 2)`` [m]), point by point within
        ``tolerance`` [m] (a polygon that came through a message has float32 points)."""
        q = np.asarray(polygon, dtype=np.float64)
        return any(p.shape == q.shape and np.allclose(p, q, rtol=0.0, atol=tolerance)
                   for p in self.polygons)

    def mask(self, grid: GridMap) -> np.ndarray:
        """``(H, W)`` bool: cell centres inside the region (all True when it is everywhere)."""
        if self.everywhere:
            return np.ones(grid.shape, bool)
        X, Y = grid.all_cell_centers()
        inside = TargetPolygons(self.polygons).inside(np.stack([X.ravel(), Y.ravel()], axis=-1))
        return inside.reshape(grid.shape)

    def restrict(self, density: np.ndarray, grid: GridMap, free: np.ndarray | None = None,
                 where: str = "region") -> np.ndarray:
        """``density (H, W)`` kept inside the region (and on ``free`` cells), 0 elsewhere;
        ConfigError if nothing of it is left (a region off the map or inside obstacles)."""
        keep = self.mask(grid) if free is None else self.mask(grid) & free
        w = np.where(keep, density, 0.0)
        if not self.everywhere and not (w > 0).any():
            raise ConfigError.at(where, "holds no free space of the map (or only where the "
                                 "importance density is 0)",
                                 [p.round(3).tolist() for p in self.polygons])
        return w

    def describe(self) -> str:
        if self.everywhere:
            return "the whole map"
        area = sum(abs(polygon_area(p)) for p in self.polygons)
        n = len(self.polygons)
        return f"{n} polygon{'s' * (n > 1)}, {area:.2f} m^2"
