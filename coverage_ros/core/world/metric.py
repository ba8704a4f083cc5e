"""A world's travel metric: an isotropic weight zeta(q) > 0 (metric tensor zeta * I,
Bhattacharya et al. 2014, Sec. 2 and Eq. 9), so that a metre costs sqrt(zeta) where the going is
hard - sand, a crowd, a slope - and geodesic cells, paths and costs follow it.

In a world file::

    metric:
      zeta: 1.0                                             # everywhere else (default 1)
      regions:                                              # shapes as for obstacles
        - {type: box, center: [3, 2], size: [2, 1], zeta: 4.0}
        - {type: circle, center: [6, 5], radius: 1.0, zeta: 9.0}

A cell takes the zeta of the last region whose shape holds its centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.obstacles import Obstacle


@dataclass(frozen=True)
class MetricRegion:
    shape: Obstacle  # where (a box, polygon, wall or circle)
    zeta: float  # > 0


@dataclass(frozen=True)
class WorldMetric:
    zeta: float = 1.0  # > 0, outside every region
    regions: tuple[MetricRegion, ...] = ()

    @property
    def is_euclidean(self) -> bool:
        return self.zeta == 1.0 and all(r.zeta == 1.0 for r in self.regions)

    def zeta_on_grid(self, grid: GridMap) -> np.ndarray:
        """``(H, W) float64`` zeta at every cell centre of ``grid``."""
        out = np.full(grid.shape, float(self.zeta))
        X, Y = grid.all_cell_centers()
        pts = np.stack([X.ravel(), Y.ravel()], axis=-1)
        for region in self.regions:
            x0, y0, x1, y1 = region.shape.bounding_box()
            near = (pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (pts[:, 1] >= y0) & (pts[:, 1] <= y1)
            idx = np.flatnonzero(near)
            if len(idx):
                inside = region.shape.distance(pts[idx]) <= 0.0
                out.ravel()[idx[inside]] = region.zeta
        return out


def zeta_on_grid(metric: WorldMetric | None, grid: GridMap) -> np.ndarray | None:
    """zeta of ``metric`` on ``grid``'s cells (any lattice: the metric is given in map
    coordinates), None where travel is Euclidean (no metric, or zeta 1 everywhere)."""
    if metric is None or metric.is_euclidean:
        return None
    return metric.zeta_on_grid(grid)


#: Charts a world file may name (``chart: {type: ...}``), with their settings and defaults.
CHART_KEYS = {"sphere": {"type": None, "cells_per_pi": 64, "cap": 6.0},
              "torus": {"type": None, "cells": 64, "R": 2.0, "r": 1.0}}


@dataclass(frozen=True)
class ChartSpec:
    """A curved surface through a coordinate chart (Bhattacharya et al. 2014, Sec. 4.1): the
    unit sphere in (colatitude, longitude), caps of ``cap`` degrees around the poles blocked,
    or a torus of axial radius ``R`` and tube radius ``r`` in (tube angle, axial angle).
    Positions, densities and starts are chart coordinates [rad]. Only ``coverage-plan`` runs on
    a chart (nothing simulates robots on a sphere)."""

    kind: str  # "sphere" | "torus"
    cells: int = 64  # sphere: cells per pi of colatitude; torus: cells per turn
    cap: float = 6.0  # [deg] sphere: blocked polar caps
    R: float = 2.0  # torus: axial radius
    r: float = 1.0  # torus: tube radius

    def lattice(self) -> GridMap:
        """The chart's grid (x: first coordinate, y: second; sphere caps occupied)."""
        if self.kind == "sphere":
            res = math.pi / self.cells
            occ = np.zeros((2 * self.cells, self.cells), np.int8)
            theta = (np.arange(self.cells) + 0.5) * res
            cap = math.radians(self.cap)
            occ[:, (theta < cap) | (theta > math.pi - cap)] = 100
            return GridMap(occ, res, (0.0, 0.0, 0.0))
        res = 2.0 * math.pi / self.cells
        return GridMap(np.zeros((self.cells, self.cells), np.int8), res, (0.0, 0.0, 0.0))
