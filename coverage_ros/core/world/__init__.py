"""The world description: arena, obstacles and maps, importance densities, robots and where
they may stand.

* :mod:`.grid` - occupancy grids in the ROS convention (:class:`GridMap`);
* :mod:`.map_server` - reading map_server maps (YAML + PGM/PNG) as nav2's map_io does;
* :mod:`.density` - importance densities and their YAML form;
* :mod:`.robot` - :class:`RobotSpec` and :class:`LidarSpec`, one per robot, end to end;
* :mod:`.spec` - :class:`WorldSpec` and its true occupancy raster;
* :mod:`.loading` - world YAML files (:func:`load_world`, :func:`load_planar_world`);
* :mod:`.metric` - travel metrics (zeta regions) and charts of curved surfaces;
* :mod:`.placement` - can a robot stand here? start checks, clusters, spawn places;
* :mod:`.team` - a team: each robot's id, start and spec (``<out>/team.yaml``).
"""

from coverage_ros.core.world.loading import load_planar_world, load_world, parse_world
from coverage_ros.core.world.obstacles import Obstacle
from coverage_ros.core.world.placement import (
    FreePlacer,
    check_pose,
    clearance,
    cluster_starts,
    parse_poses,
    validate_starts,
)
from coverage_ros.core.world.robot import LidarSpec, RobotSpec
from coverage_ros.core.world.spec import StartPose, WorldSpec
from coverage_ros.core.world.team import TeamMember, load_team, parse_team, write_team

__all__ = ["FreePlacer", "LidarSpec", "Obstacle", "RobotSpec", "StartPose", "TeamMember",
           "WorldSpec", "check_pose", "clearance", "cluster_starts", "load_planar_world",
           "load_team", "load_world", "parse_poses", "parse_team", "parse_world",
           "validate_starts", "write_team"]
