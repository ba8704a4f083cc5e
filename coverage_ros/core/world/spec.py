"""A world as the stack knows it: arena, obstacles or a map, start poses, importance density
and default robot (:class:`WorldSpec`), and its true occupancy raster (:func:`rasterize_world`).

Built from YAML by :mod:`coverage_ros.core.world.loading`; where robots may stand is answered by
:mod:`coverage_ros.core.world.placement`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from coverage_ros.core.world.density import Density, UniformDensity
from coverage_ros.core.world.grid import FREE, OCCUPIED, GridMap
from coverage_ros.core.world.metric import ChartSpec, WorldMetric, zeta_on_grid
from coverage_ros.core.world.obstacles import Obstacle
from coverage_ros.core.world.robot import RobotSpec

#: [m] raster of worlds without a map (nav2 maps' usual resolution)
DEFAULT_RESOLUTION = 0.05


@dataclass(frozen=True)
class StartPose:
    x: float
    y: float
    yaw: float
    robot: RobotSpec


@dataclass(frozen=True)
class WorldSpec:
    """A validated world; :attr:`grid` is its true occupancy raster (what ``/map`` shows)."""

    name: str
    source: str  # the file it came from ("" if built in code)
    resolution: float
    bounds: tuple[float, float, float, float] | None  # walled arena, or None
    base_map: GridMap | None
    obstacles: tuple[Obstacle, ...] = ()
    starts: tuple[StartPose, ...] = ()
    density: Density = field(default_factory=UniformDensity)
    robot: RobotSpec = field(default_factory=RobotSpec)  # default for robots without a start
    #: The travel metric (:class:`coverage_ros.core.world.metric.WorldMetric`), None: Euclidean.
    metric: WorldMetric | None = None
    #: A curved surface through a chart (coordinates, metric, blocked caps), None: the plane.
    chart: ChartSpec | None = None

    @cached_property
    def zeta(self) -> np.ndarray | None:
        """``(H, W)`` isotropic metric weight on :attr:`grid`, None where the world is
        Euclidean (domains are built with it: ``CoverageDomain.from_world``)."""
        return zeta_on_grid(self.metric, self.grid)

    @cached_property
    def grid(self) -> GridMap:
        """The true world as an occupancy grid (obstacles 100, free 0, map unknowns kept)."""
        return rasterize_world(self)

    @cached_property
    def solid(self) -> np.ndarray:
        """``(H, W) bool``: the cells of :attr:`grid` that are occupied for certain - the whole
        cell lies in obstacles (each of its four corners lies in one), outside the arena or on
        a blocked map cell. :attr:`grid` also marks cells an obstacle only reaches into
        (within half a cell of the centre), which a lidar may rightly see partly free: a beam
        that grazes a wall whose face runs through a row of cells near their centres passes
        through the free half of each."""
        bare = rasterize_world(self, with_obstacles=False).occupied_mask(
            unknown_is_occupied=False)  # outside the arena, blocked on the map
        grid = self.grid
        X, Y = grid.all_cell_centers()
        half = 0.5 * grid.resolution
        whole = np.zeros((4,) + grid.shape, dtype=bool)  # each corner in an obstacle
        corners = ((-half, -half), (half, -half), (-half, half), (half, half))
        for obs in self.obstacles:
            bx0, by0, bx1, by1 = obs.bounding_box()
            sel = (X >= bx0 - half) & (X <= bx1 + half) & (Y >= by0 - half) & (Y <= by1 + half)
            if not sel.any():
                continue
            xs, ys = X[sel], Y[sel]
            for k, (dx, dy) in enumerate(corners):
                whole[k][sel] |= obs.distance(np.stack([xs + dx, ys + dy], axis=-1)) <= 1e-9
        return bare | whole.all(axis=0)

    def robot_spec(self, index: int) -> RobotSpec:
        """The spec of robot ``index`` (its start entry's, else the world default)."""
        return self.starts[index].robot if index < len(self.starts) else self.robot


def rasterize_world(spec: WorldSpec, reach: float | None = None,
                    with_obstacles: bool = True) -> GridMap:
    """A cell is occupied if an obstacle comes within ``reach`` [m] of its centre (default half
    a cell; no obstacle counts without ``with_obstacles``), or the cell centre lies outside the
    arena bounds."""
    res = spec.resolution
    if spec.base_map is not None:
        base = spec.base_map
        occ = base.occupancy.astype(np.int8).copy()
        grid = base
    else:
        assert spec.bounds is not None
        xmin, ymin, xmax, ymax = spec.bounds
        # One ring of wall cells around the arena so /map shows its boundary.
        width = int(math.ceil((xmax - xmin) / res - 1e-9)) + 2
        height = int(math.ceil((ymax - ymin) / res - 1e-9)) + 2
        occ = np.full((height, width), FREE, dtype=np.int8)
        grid = GridMap(occ.copy(), res, (xmin - res, ymin - res, 0.0))
    X, Y = grid.all_cell_centers()
    if spec.bounds is not None:
        xmin, ymin, xmax, ymax = spec.bounds
        outside = (X < xmin) | (X > xmax) | (Y < ymin) | (Y > ymax)
        occ[outside] = OCCUPIED
    half = 0.5 * res if reach is None else reach
    for obs in spec.obstacles if with_obstacles else ():
        bx0, by0, bx1, by1 = obs.bounding_box()
        sel = (X >= bx0 - res) & (X <= bx1 + res) & (Y >= by0 - res) & (Y <= by1 + res)
        if not sel.any():
            continue
        pts = np.stack([X[sel], Y[sel]], axis=-1)
        hit = obs.distance(pts) <= half
        idx = np.flatnonzero(sel.ravel())[hit]
        occ.ravel()[idx] = OCCUPIED
    return grid.with_occupancy(occ)

