"""All ROS message <-> numpy/python conversions of coverage_ros, in one place.

Conventions (REP 103 / REP 105 / REP 117)
-----------------------------------------
* Units SI: metres, radians, seconds. Axes right-handed, x forward, y left, z up; yaw is the
  counter-clockwise angle about z from the map's x axis, wrapped to [-pi, pi).
* Frames: ``map`` is the world (the simulator's ground truth and ``/map``). Robot ``<id>`` with
  prefix ``robot_`` has ``robot_<id>/odom`` (fixed to the world at the robot's spawn pose: odom
  pose (0, 0, 0) is where the robot appeared), ``robot_<id>/base_link`` (robot centre on the
  floor, x forward) and ``robot_<id>/base_scan`` (the lidar; same origin and axes as
  ``base_link`` in this simulator).
* Time stamps are simulation time (``/clock``); :func:`to_time_msg` turns seconds into
  ``builtin_interfaces/Time``.
* Occupancy grids follow nav_msgs/OccupancyGrid exactly as
  :class:`~coverage_ros.core.world.grid.GridMap` does: row 0 at the origin (lowest y), row-major
  ``data``, 0 free, 100 occupied, -1 unknown.
* Laser scans: beam ``k`` at ``angle_min + k * angle_increment`` in ``base_scan``, counter-
  clockwise; ranges in metres, ``+inf`` no return within ``range_max``, ``-inf`` closer than
  ``range_min`` (REP 117).
* Velocity commands (``cmd_vel``): ``linear.x`` [m/s] forward and ``angular.z`` [rad/s]
  counter-clockwise in ``base_link``; the other components are ignored (differential drive).
* Coverage state (``coverage_state``): a ``coverage_msgs/RobotState`` in the ``map`` frame:
  the generator ``x``, ``y`` [m], power weight, body, velocity, last update, mode and each
  strategy's own values in typed fields; inside the stack a mapping of named values (see
  :mod:`.state`). The world's ``/world/robots``: ``coverage_msgs/WorldStatus``.
* Cells (``cell``): a ``nav_msgs/OccupancyGrid`` cropped to the cell's bounding box, on the
  map's cell lattice: 100 = part of the robot's cell, 0 = not.

* Exploration evidence (``observations``): a ``sensor_msgs/PointCloud2``, a point per cell, fields
  ``x``, ``y`` (the cell centre [m], ``map`` frame), ``hits``, ``misses`` (the sender's counts);
  see :mod:`.evidence`.

* Lock-step (``/world/tick``, ``/world/tick_report``): ``coverage_msgs/LockstepTick`` and
  ``LockstepReport``; stamps compared as integer nanoseconds; see :mod:`.lockstep`.

* Transforms (``/tf``, ``/tf_static``): ``tf2_msgs/TFMessage`` of planar ``TransformStamped``;
  see :mod:`.tf`.
* RViz markers (``/coverage/markers``): one marker per robot and kind, id = robot id, namespace =
  kind; see :mod:`.markers`.

The conversions are grouped by topic kind in :mod:`.basics`, :mod:`.grids`, :mod:`.motion`,
:mod:`.team`, :mod:`.state`, :mod:`.evidence`, :mod:`.lockstep`, :mod:`.markers` and
:mod:`.tf`, and all re-exported here: nodes use ``conv.<name>``.

Arrays cross the message boundary with ``array.array`` (``tobytes``/``np.frombuffer``): element-
wise assignment of a numpy array to a message sequence is ~60x slower.
"""

from coverage_ros.nodes.conversions.basics import (
    MAP_FRAME,
    RobotFrames,
    clock_msg,
    from_time_msg,
    quaternion_problem,
    quaternion_to_yaw,
    stamp_problem,
    to_time_msg,
    yaw_to_quaternion,
)
from coverage_ros.nodes.conversions.evidence import evidence_from_msg, evidence_msg
from coverage_ros.nodes.conversions.grids import grid_to_occupancy_grid, occupancy_grid_to_grid
from coverage_ros.nodes.conversions.lockstep import (
    ns_time_msg,
    report_msg,
    stamp_ns,
    tick_from_msg,
    tick_msg,
)
from coverage_ros.nodes.conversions.markers import (
    MARKER_KINDS,
    RobotMarkers,
    delete_marker,
    robot_markers,
    team_markers,
)
from coverage_ros.nodes.conversions.motion import (
    command_to_twist,
    laser_scan_msg,
    laser_scan_to_ranges,
    odometry_msg,
    odometry_to_pose,
    twist_to_command,
)
from coverage_ros.nodes.conversions.state import (
    coverage_state_msg,
    coverage_state_values,
    world_status_msg,
    world_status_robots,
)
from coverage_ros.nodes.conversions.team import (
    SpawnRequest,
    cell_grid_msg,
    cell_grid_to_grid,
    parse_spawn_request,
    path_msg,
    path_to_points,
    polygon_msg,
    polygon_to_points,
    pose_stamped_msg,
    pose_stamped_to_pose,
    scan_to_points,
)
from coverage_ros.nodes.conversions.tf import TFMessage, tf_message, transform_msg, transforms_of

__all__ = [
    "MAP_FRAME",
    "MARKER_KINDS",
    "RobotFrames",
    "RobotMarkers",
    "SpawnRequest",
    "TFMessage",
    "cell_grid_msg",
    "cell_grid_to_grid",
    "clock_msg",
    "command_to_twist",
    "coverage_state_msg",
    "coverage_state_values",
    "delete_marker",
    "evidence_from_msg",
    "evidence_msg",
    "from_time_msg",
    "grid_to_occupancy_grid",
    "laser_scan_msg",
    "laser_scan_to_ranges",
    "ns_time_msg",
    "occupancy_grid_to_grid",
    "odometry_msg",
    "odometry_to_pose",
    "parse_spawn_request",
    "path_msg",
    "path_to_points",
    "polygon_msg",
    "polygon_to_points",
    "pose_stamped_msg",
    "pose_stamped_to_pose",
    "quaternion_problem",
    "quaternion_to_yaw",
    "report_msg",
    "robot_markers",
    "scan_to_points",
    "stamp_ns",
    "stamp_problem",
    "team_markers",
    "tf_message",
    "tick_from_msg",
    "tick_msg",
    "to_time_msg",
    "transform_msg",
    "transforms_of",
    "twist_to_command",
    "world_status_msg",
    "world_status_robots",
    "yaw_to_quaternion",
]
