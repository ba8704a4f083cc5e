"""The coverage domain of a world file: its map inflated by the robot's radius with its density
and travel metric, or the domain of its chart (a curved surface)."""

from __future__ import annotations

from coverage_ros.core.geodesic.charts import chart_domain
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.world.density import Density
from coverage_ros.core.world.spec import WorldSpec


def world_domain(world: WorldSpec, robot_radius: float, density: Density | None = None,
                 connectivity: int = 8) -> CoverageDomain:
    """Domain of a disc robot of ``robot_radius`` [m] on ``world``'s true map, with its density
    (or ``density``) and its travel metric (``metric:`` in the world file), or the world's
    chart (a curved surface, whose coordinates are angles: the robot is a point there)."""
    density = world.density if density is None else density
    if world.chart is not None:
        return chart_domain(world.chart, density, connectivity)
    return CoverageDomain.from_grid(world.grid, robot_radius, density,
                                    connectivity=connectivity, zeta=world.zeta)
