"""Coverage on curved surfaces through a coordinate chart (Bhattacharya et al. 2014, section 4.1).

The domain is a uniform grid over the chart's coordinates, with the surface's metric tensor at
every cell, wrap-around edges where a coordinate is periodic, and on the sphere "invisible"
edges across small cordoned-off polar caps (the chart is singular at the poles).

Grid axes: ``x`` (columns) is the first chart coordinate, ``y`` (rows) the second, and the map
frame of these domains *is* the chart (origin 0, no rotation), so positions are coordinates.
"""

from __future__ import annotations

import math

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.graph import build_grid_graph
from coverage_ros.core.world.density import Density, density_on_grid
from coverage_ros.core.world.grid import FREE, OCCUPIED, GridMap
from coverage_ros.core.world.metric import ChartSpec
from coverage_ros.errors import ConfigError


def sphere_domain(cells_per_pi: int = 64, cap: float = math.radians(6.0),
                  density: Density | None = None, connectivity: int = 8) -> CoverageDomain:
    """The unit sphere in (colatitude theta in [0, pi], longitude phi in [0, 2 pi)).

    Metric ``diag(1, sin^2 theta)``; longitude wraps; caps of angular radius ``cap`` [rad]
    around both poles are blocked and crossed by edges joining diametrically opposite cells
    (length: the great-circle arc through the pole).
    """
    if cells_per_pi < 8:
        raise ConfigError.at("cells_per_pi", "must be >= 8", cells_per_pi)
    res = math.pi / cells_per_pi
    W, H = cells_per_pi, 2 * cells_per_pi  # columns: theta, rows: phi
    theta = (np.arange(W) + 0.5) * res
    occ = np.full((H, W), FREE, dtype=np.int8)
    blocked_cols = (theta < cap) | (theta > math.pi - cap)
    occ[:, blocked_cols] = OCCUPIED
    tensor = np.zeros((H, W, 2, 2))
    tensor[..., 0, 0] = 1.0
    tensor[..., 1, 1] = np.maximum(np.sin(theta), 1e-6)[None, :] ** 2
    free = occ == FREE
    free_cols = np.flatnonzero(~blocked_cols)
    north, south = int(free_cols[0]), int(free_cols[-1])
    rows = np.arange(H)
    u, v, w = [], [], []
    for col, across in ((north, 2.0 * theta[north]), (south, 2.0 * (math.pi - theta[south]))):
        opposite = (rows + H // 2) % H
        half = rows < H // 2
        u.append(rows[half] * W + col)
        v.append(opposite[half] * W + col)
        w.append(np.full(int(half.sum()), across))
    extra = (np.concatenate(u), np.concatenate(v), np.concatenate(w))
    graph = build_grid_graph(free, res, connectivity=connectivity, tensor=tensor,
                             wrap=(True, False), extra_edges=extra)
    geometry = GridMap(occ, res, (0.0, 0.0, 0.0))
    w_grid = density_on_grid(density, geometry, free) if density else free.astype(np.float64)
    return CoverageDomain(geometry=geometry, graph=graph, density=w_grid, tensor=tensor)


def torus_domain(cells: int = 64, R: float = 2.0, r: float = 1.0,
                 obstacles: tuple[tuple[float, float, float, float], ...] = (),
                 density: Density | None = None, connectivity: int = 8) -> CoverageDomain:
    """A torus with axial radius ``R`` and tube radius ``r`` in (tube angle x, axial angle y),
    both in [0, 2 pi) and wrapping. Metric ``diag(r^2, (R + r cos x)^2)``. ``obstacles`` are
    chart rectangles ``(x0, y0, x1, y1)`` [rad]."""
    if not R > r > 0:
        raise ConfigError.at("torus", "need R > r > 0", (R, r))
    res = 2.0 * math.pi / cells
    x = (np.arange(cells) + 0.5) * res
    y = (np.arange(cells) + 0.5) * res
    occ = np.full((cells, cells), FREE, dtype=np.int8)
    for x0, y0, x1, y1 in obstacles:
        occ[np.ix_((y >= y0) & (y <= y1), (x >= x0) & (x <= x1))] = OCCUPIED
    tensor = np.zeros((cells, cells, 2, 2))
    tensor[..., 0, 0] = r * r
    tensor[..., 1, 1] = ((R + r * np.cos(x)) ** 2)[None, :]
    free = occ == FREE
    graph = build_grid_graph(free, res, connectivity=connectivity, tensor=tensor,
                             wrap=(True, True))
    geometry = GridMap(occ, res, (0.0, 0.0, 0.0))
    w_grid = density_on_grid(density, geometry, free) if density else free.astype(np.float64)
    return CoverageDomain(geometry=geometry, graph=graph, density=w_grid, tensor=tensor)


def wrap_chart_position(domain: CoverageDomain, point: np.ndarray) -> np.ndarray:
    """Bring a chart position back into the chart's periodic range."""
    p = np.asarray(point, dtype=np.float64).copy()
    H, W = domain.shape
    res = domain.resolution
    if domain.graph.wrap[1]:
        p[0] %= W * res
    if domain.graph.wrap[0]:
        p[1] %= H * res
    return p


def chart_domain(chart: ChartSpec, density: Density | None = None,
                 connectivity: int = 8) -> CoverageDomain:
    """The domain of a world file's ``chart`` (see :class:`ChartSpec`)."""
    if chart.kind == "sphere":
        return sphere_domain(chart.cells, math.radians(chart.cap), density, connectivity)
    return torus_domain(chart.cells, chart.R, chart.r, density=density,
                        connectivity=connectivity)
