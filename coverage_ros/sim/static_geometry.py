"""The static world as geometry: what robots collide with and what the lidar sees.

Built once from a :class:`~coverage_ros.core.world.WorldSpec` (pure numpy; :func:`add_to_space`
puts it into a pymunk space):

* explicit obstacles exactly: convex polygons as polygons, concave ones as their edges, circles
  as circles;
* the arena ``bounds`` as four thick boxes just outside the arena;
* a map_server base map's blocked cells (occupied, and unknown treated as blocked) as the grid
  edges between blocked and free cells, merged along rows and columns into long axis-aligned
  segments. A robot can only ever touch that boundary, so the interior of large blocked areas
  costs nothing (the 1674 x 1006 warehouse map becomes ~10k segments).

All coordinates are metres in the ``map`` frame. ``segments`` holds *every* surface a ray can
hit (polygon edges, the arena's inner walls, the map boundary); circles are kept analytic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coverage_ros.core.geometry import polygon_area
from coverage_ros.core.world import WorldSpec
from coverage_ros.core.world.grid import GridMap

ARENA_WALL_THICKNESS = 0.5  # [m] boxes outside the arena; far thicker than a physics step's travel


@dataclass(frozen=True)
class StaticGeometry:
    """Static surfaces of a world.

    Attributes
    ----------
    segments : (S, 4) float64
        ``[ax, ay, bx, by]`` [m]: every straight surface a ray can hit.
    circles : (C, 3) float64
        ``[cx, cy, r]`` [m]: circular obstacles.
    convex_polygons : tuple of (M, 2) float64
        Solid convex bodies for physics (convex obstacles and the arena's wall boxes).
    physics_segments : (K, 4) float64
        Zero-thickness walls for physics: the map boundary and the edges of concave obstacles.
    """

    segments: np.ndarray
    circles: np.ndarray
    convex_polygons: tuple[np.ndarray, ...]
    physics_segments: np.ndarray

    @property
    def shape_count(self) -> int:
        """Number of pymunk shapes :func:`add_to_space` creates."""
        return len(self.circles) + len(self.convex_polygons) + len(self.physics_segments)


def is_convex(polygon: np.ndarray) -> bool:
    """Whether a simple polygon ``(M, 2)`` is convex (collinear vertices allowed)."""
    p = np.asarray(polygon, dtype=np.float64)
    e = np.roll(p, -1, axis=0) - p
    cross = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
    scale = max(float(np.abs(cross).max()), 1e-300)
    return bool(np.all(cross >= -1e-12 * scale) or np.all(cross <= 1e-12 * scale))


def polygon_edge_segments(polygon: np.ndarray) -> np.ndarray:
    """``(M, 4)`` edges ``[ax, ay, bx, by]`` of a closed polygon."""
    p = np.asarray(polygon, dtype=np.float64)
    return np.hstack([p, np.roll(p, -1, axis=0)])


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of ``True`` along each row of a ``(R, C)`` mask: ``(row, start, end)`` with ``end``
    exclusive, each ``(K,) int64``."""
    padded = np.zeros((mask.shape[0], mask.shape[1] + 2), dtype=np.int8)
    padded[:, 1:-1] = mask
    d = np.diff(padded, axis=1)
    rows, starts = np.nonzero(d == 1)
    _, ends = np.nonzero(d == -1)  # row-major order pairs each start with its end
    return rows, starts, ends


def grid_boundary_segments(grid: GridMap, blocked: np.ndarray) -> np.ndarray:
    """``(S, 4)`` [m] map-frame segments along the grid lines separating blocked from free cells.

    ``blocked`` is ``(H, W) bool``; cells outside the grid count as blocked, so free cells on the
    border get a wall on the grid's edge. Collinear unit edges are merged into one segment.
    """
    b = np.pad(np.asarray(blocked, dtype=bool), 1, constant_values=True)
    # Horizontal edge on grid line y = r between cells (r-1, c) and (r, c): (H+1, W).
    horizontal = b[:-1, 1:-1] != b[1:, 1:-1]
    # Vertical edge on grid line x = c between cells (r, c-1) and (r, c): (W+1, H) after .T.
    vertical = (b[1:-1, :-1] != b[1:-1, 1:]).T
    hy, hx0, hx1 = _runs(horizontal)
    vx, vy0, vy1 = _runs(vertical)
    a = np.concatenate([np.column_stack([hx0, hy]), np.column_stack([vx, vy0])]).astype(float)
    e = np.concatenate([np.column_stack([hx1, hy]), np.column_stack([vx, vy1])]).astype(float)
    if len(a) == 0:
        return np.zeros((0, 4))
    return np.hstack([grid.grid_to_world(a), grid.grid_to_world(e)])


def arena_wall_boxes(bounds: tuple[float, float, float, float],
                     thickness: float = ARENA_WALL_THICKNESS) -> tuple[np.ndarray, ...]:
    """Four ``(4, 2)`` counter-clockwise boxes enclosing the arena from outside."""
    xmin, ymin, xmax, ymax = bounds
    t = thickness

    def box(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)

    return (box(xmin - t, ymin - t, xmax + t, ymin), box(xmin - t, ymax, xmax + t, ymax + t),
            box(xmin - t, ymin, xmin, ymax), box(xmax, ymin, xmax + t, ymax))


def build_static_geometry(spec: WorldSpec) -> StaticGeometry:
    """The static surfaces of ``spec`` (see module docstring)."""
    segments: list[np.ndarray] = []
    physics: list[np.ndarray] = []
    convex: list[np.ndarray] = []
    circles: list[tuple[float, float, float]] = []
    for obs in spec.obstacles:
        if obs.polygon is not None:
            poly = np.asarray(obs.polygon, dtype=np.float64)
            if polygon_area(poly) < 0:
                poly = poly[::-1].copy()
            edges = polygon_edge_segments(poly)
            segments.append(edges)
            if is_convex(poly):
                convex.append(poly)
            else:
                physics.append(edges)
        else:
            assert obs.center is not None
            circles.append((float(obs.center[0]), float(obs.center[1]), float(obs.radius)))
    if spec.bounds is not None:
        xmin, ymin, xmax, ymax = spec.bounds
        inner = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
        segments.append(polygon_edge_segments(inner))
        convex.extend(arena_wall_boxes(spec.bounds))
    if spec.base_map is not None:
        edges = grid_boundary_segments(spec.base_map, spec.base_map.occupied_mask())
        segments.append(edges)
        physics.append(edges)
    return StaticGeometry(
        segments=np.concatenate(segments) if segments else np.zeros((0, 4)),
        circles=np.array(circles, dtype=np.float64).reshape(-1, 3),
        convex_polygons=tuple(convex),
        physics_segments=np.concatenate(physics) if physics else np.zeros((0, 4)),
    )
