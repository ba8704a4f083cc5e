"""A domain cut down to the window that holds its free space.

Maps from SLAM or ``map_server`` often keep wide unknown margins around the mapped part
(``tb3_sandbox``: 384 x 384 cells, its free space in 99 x 107 of them). Every whole-domain
search and sum costs in proportion to the grid, blocked cells included, so a team step on the
window alone does the same work on a fraction of the cells. Nothing outside the window can
matter: graph edges join free cells only, a line of sight between two free cells stays in their
bounding box, and the window keeps a ring of blocked cells around the free space as wide as the
robot's inflation (the occluders next to it, the obstacles clearances are measured to).

Its first row and column are multiples of the line-of-sight tile
(:data:`~coverage_ros.core.geodesic.tangents.SIGHT_TILE`), so tiles cover the same cells; the
cut domain takes points and tie biases in the whole grid's coordinates less a whole number of
cells (:attr:`CoverageDomain.cut_from`: exact) and keeps the whole domain's angular bins of
line-of-sight depth maps (:attr:`~coverage_ros.core.geodesic.sight.LineOfSight.depth_bins`).
So the cells, distances and sums are the whole domain's bit for bit, and map-frame results
differ by rounding only.
"""

from __future__ import annotations

import math

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.graph import build_grid_graph, neighbourhood
from coverage_ros.core.geodesic.tangents import SIGHT_TILE
from coverage_ros.core.world.grid import GridMap

__all__ = ["cropped", "free_window", "window_of"]

#: a window is cut only where it leaves out at least this share of the grid's cells (a few
#: percent saved does not pay for a second domain's tables)
LEAVES_OUT = 0.25


def free_window(domain: CoverageDomain) -> tuple[slice, slice] | None:
    """``(rows, cols)``: the window of ``domain`` that holds its free cells and a ring of
    blocked ones, its start aligned to the line-of-sight tiles; None where the domain cannot be
    cut (a chart, a wrapping or extra-edged graph, no free cell) or the window would keep more
    than ``1 - LEAVES_OUT`` of the grid."""
    graph = domain.graph
    if (domain.tensor is not None or any(graph.wrap) or graph.extra_edges is not None
            or not domain.free.any()):
        return None
    if len(graph.offsets) not in (8, 16) or not np.array_equal(
            graph.offsets, neighbourhood(len(graph.offsets))):
        return None
    H, W = domain.shape
    rows = np.flatnonzero(domain.free.any(axis=1))
    cols = np.flatnonzero(domain.free.any(axis=0))
    ring = 1 + math.ceil(domain.robot_radius / domain.resolution)  # [cells] (the inflation too)
    r0 = max(int(rows[0]) - ring, 0) // SIGHT_TILE * SIGHT_TILE
    c0 = max(int(cols[0]) - ring, 0) // SIGHT_TILE * SIGHT_TILE
    r1, c1 = min(int(rows[-1]) + 1 + ring, H), min(int(cols[-1]) + 1 + ring, W)
    if (r1 - r0) * (c1 - c0) > (1.0 - LEAVES_OUT) * H * W:
        return None
    return slice(r0, r1), slice(c0, c1)


def cropped(domain: CoverageDomain, window: tuple[slice, slice]) -> CoverageDomain:
    """The domain on ``window`` (:func:`free_window`): its map cut out, the same free cells,
    density and metric weight there, and the whole grid with the offset of its first cell."""
    rows, cols = window
    grid = domain.geometry
    origin = grid.grid_to_world(np.array([[cols.start, rows.start]], dtype=np.float64))[0]
    sub = GridMap(grid.occupancy[rows, cols], grid.resolution,
                  (float(origin[0]), float(origin[1]), grid.origin[2]))
    zeta = None if domain.zeta is None else np.ascontiguousarray(domain.zeta[rows, cols])
    free = np.ascontiguousarray(domain.free[rows, cols])
    graph = build_grid_graph(free, grid.resolution, connectivity=len(domain.graph.offsets),
                             zeta=zeta)
    whole, (c0, r0) = domain.cut_from or (grid, (0, 0))
    cut = CoverageDomain(sub, graph, np.ascontiguousarray(domain.density[rows, cols]),
                         zeta=zeta, robot_radius=domain.robot_radius,
                         unknown_is_free=domain.unknown_is_free,
                         cut_from=(whole, (c0 + cols.start, r0 + rows.start)))
    cut._cache["depth_bins"] = domain.depth_bins  # (the angular bins decide what is seen)
    return cut


def window_of(domain: CoverageDomain, points: np.ndarray
              ) -> tuple[CoverageDomain, tuple[slice, slice]] | None:
    """The cut domain of ``domain`` and its window (made once, kept in the domain's cache) when
    it has one and every map-frame point of ``points (n, 2)`` lies on a free cell (a point off
    the free space snaps to its nearest free cell over the whole grid); else None."""
    key = "free_window"
    if key not in domain._cache:
        window = free_window(domain)
        domain._cache[key] = None if window is None else (cropped(domain, window), window)
    cut: tuple[CoverageDomain, tuple[slice, slice]] | None = domain._cache[key]
    if cut is None or not domain.free_at_grid(domain.to_grid(points))[2].all():
        return None
    return cut
