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
* Occupancy grids follow nav_msgs/OccupancyGrid exactly as :class:`~coverage_ros.core.grid.GridMap`
  does: row 0 at the origin (lowest y), row-major ``data``, 0 free, 100 occupied, -1 unknown.
* Laser scans: beam ``k`` at ``angle_min + k * angle_increment`` in ``base_scan``, counter-
  clockwise; ranges in metres, ``+inf`` no return within ``range_max``, ``-inf`` closer than
  ``range_min`` (REP 117).
* Velocity commands (``cmd_vel``): ``linear.x`` [m/s] forward and ``angular.z`` [rad/s]
  counter-clockwise in ``base_link``; the other components are ignored (differential drive).
* Coverage state (``coverage_state``): a ``sensor_msgs/JointState`` used as a stamped vector of
  named values in the ``map`` frame: ``name[k]`` / ``position[k]`` pairs ``x``, ``y`` (the
  generator [m]), ``weight`` (power weight R [m]), ``mass``, ``cost``, ``update_ms``, and for
  some strategies ``virtual_x``/``virtual_y`` (virtual generator [m]) and further extras.
* Cells (``cell``): a ``nav_msgs/OccupancyGrid`` cropped to the cell's bounding box, on the
  map's cell lattice: 100 = part of the robot's cell, 0 = not.

Arrays cross the message boundary with ``array.array`` (``tobytes``/``np.frombuffer``): element-
wise assignment of a numpy array to a message sequence is ~60x slower.
"""

from __future__ import annotations

import array
import math
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
import yaml
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point32, PolygonStamped, PoseStamped, Quaternion, Twist
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, LaserScan

from coverage_ros.core.grid import GridMap
from coverage_ros.core.world import LidarSpec, RobotSpec
from coverage_ros.errors import ConfigError

MAP_FRAME = "map"


# ---------------------------------------------------------------------------- time and angles
def to_time_msg(seconds: float) -> Time:
    """Sim time [s] -> ``builtin_interfaces/Time``."""
    ns = round(seconds * 1e9)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def from_time_msg(stamp: Time) -> float:
    """``builtin_interfaces/Time`` -> seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def clock_msg(seconds: float) -> Clock:
    return Clock(clock=to_time_msg(seconds))


def yaw_to_quaternion(yaw: float) -> Quaternion:
    """A rotation of ``yaw`` [rad] about z."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(0.5 * yaw), w=math.cos(0.5 * yaw))


def quaternion_to_yaw(q: Quaternion) -> float:
    """Yaw [rad] of a quaternion (its rotation about z, for planar poses)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


# ---------------------------------------------------------------------------- frames
@dataclass(frozen=True)
class RobotFrames:
    """Names of one robot's namespace and frames (see module docstring)."""

    namespace: str  # "/robot_3"
    odom: str  # "robot_3/odom"
    base_link: str  # "robot_3/base_link"
    base_scan: str  # "robot_3/base_scan"

    @classmethod
    def of(cls, prefix: str, robot_id: int) -> RobotFrames:
        name = f"{prefix}{robot_id}"
        return cls(f"/{name}", f"{name}/odom", f"{name}/base_link", f"{name}/base_scan")

    def topic(self, name: str) -> str:
        return f"{self.namespace}/{name}"


# ---------------------------------------------------------------------------- maps
def grid_to_occupancy_grid(grid: GridMap, stamp: Time, frame_id: str = MAP_FRAME) -> OccupancyGrid:
    """A :class:`GridMap` as ``nav_msgs/OccupancyGrid`` (fast: ~1 ms per million cells)."""
    msg = OccupancyGrid()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.info.map_load_time = stamp
    msg.info.resolution = float(grid.resolution)
    msg.info.width = grid.width
    msg.info.height = grid.height
    x, y, yaw = grid.origin
    msg.info.origin.position.x = float(x)
    msg.info.origin.position.y = float(y)
    msg.info.origin.orientation = yaw_to_quaternion(yaw)
    msg.data = array.array("b", grid.occupancy.astype(np.int8).tobytes())
    return msg


def occupancy_grid_to_grid(msg: OccupancyGrid) -> GridMap:
    """``nav_msgs/OccupancyGrid`` -> :class:`GridMap` (raises ConfigError if inconsistent)."""
    h, w = msg.info.height, msg.info.width
    data = (np.frombuffer(msg.data, dtype=np.int8) if isinstance(msg.data, array.array)
            else np.asarray(msg.data, dtype=np.int8))
    if data.size != h * w:
        raise ConfigError.at("OccupancyGrid.data", "size does not match width * height",
                             data.size, str(h * w))
    o = msg.info.origin
    return GridMap(data.reshape(h, w), msg.info.resolution,
                   (o.position.x, o.position.y, quaternion_to_yaw(o.orientation)))


# ---------------------------------------------------------------------------- odometry
def odometry_msg(stamp: Time, frame_id: str, child_frame_id: str,
                 pose: tuple[float, float, float], twist: tuple[float, float, float],
                 variance: tuple[float, float] = (0.0, 0.0),
                 out: Odometry | None = None) -> Odometry:
    """``nav_msgs/Odometry`` of a planar pose ``(x, y, yaw)`` in ``frame_id`` and a body-frame
    twist ``(vx, vy, w)`` in ``child_frame_id``; ``variance`` = ``(var_xy [m^2], var_yaw
    [rad^2])`` goes on the pose covariance diagonal. Pass ``out`` to refill a message instead of
    building one (an ``Odometry()`` costs ~60 us; publishing serializes it right away)."""
    msg = Odometry() if out is None else out
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    msg.pose.pose.position.x = float(pose[0])
    msg.pose.pose.position.y = float(pose[1])
    msg.pose.pose.orientation = yaw_to_quaternion(pose[2])
    if variance[0] or variance[1] or out is not None:
        cov = msg.pose.covariance
        cov[0] = cov[7] = float(variance[0])
        cov[35] = float(variance[1])
    msg.twist.twist.linear.x = float(twist[0])
    msg.twist.twist.linear.y = float(twist[1])
    msg.twist.twist.angular.z = float(twist[2])
    return msg


def odometry_to_pose(msg: Odometry) -> tuple[float, float, float]:
    """``(x, y, yaw)`` of an ``nav_msgs/Odometry`` message, in its header frame."""
    p = msg.pose.pose
    return p.position.x, p.position.y, quaternion_to_yaw(p.orientation)


# ---------------------------------------------------------------------------- laser scans
def laser_scan_msg(ranges: np.ndarray, lidar: LidarSpec, stamp: Time, frame_id: str) -> LaserScan:
    """``sensor_msgs/LaserScan`` from ``(B,)`` ranges [m] (REP 117 values kept)."""
    msg = LaserScan()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.angle_min = float(lidar.angle_min)
    msg.angle_increment = float(lidar.angle_increment)
    msg.angle_max = float(lidar.angle_min + lidar.angle_increment * (lidar.beams - 1))
    msg.time_increment = 0.0  # the simulated scan is instantaneous
    msg.scan_time = float(1.0 / lidar.rate_hz)
    msg.range_min = float(lidar.range_min)
    msg.range_max = float(lidar.range_max)
    msg.ranges = array.array("f", np.asarray(ranges, dtype=np.float32).tobytes())
    return msg


def laser_scan_to_ranges(msg: LaserScan) -> tuple[np.ndarray, np.ndarray]:
    """``(angles, ranges)``, each ``(B,) float64``: beam angles [rad] in the scan frame and
    ranges [m] (inf/-inf kept)."""
    ranges = np.asarray(msg.ranges, dtype=np.float64)
    angles = msg.angle_min + msg.angle_increment * np.arange(len(ranges))
    return angles, ranges


# ---------------------------------------------------------------------------- commands
def twist_to_command(msg: Twist) -> tuple[float, float]:
    """``(v [m/s], w [rad/s])`` of a ``cmd_vel`` twist; ValueError if not finite."""
    v, w = float(msg.linear.x), float(msg.angular.z)
    if not (math.isfinite(v) and math.isfinite(w)):
        raise ValueError(f"cmd_vel must be finite (got linear.x={v!r}, angular.z={w!r})")
    return v, w


def command_to_twist(v: float, w: float) -> Twist:
    msg = Twist()
    msg.linear.x = float(v)
    msg.angular.z = float(w)
    return msg


# ---------------------------------------------------------------------------- spawn requests
_SPAWN_ROBOT_KEYS = {f.name for f in fields(RobotSpec)} - {"lidar"}


@dataclass(frozen=True)
class SpawnRequest:
    """A parsed ``/world/spawn`` payload: ``{id: 7, pose: [x, y, yaw], radius: 0.15, ...}``
    (``id`` None: the smallest free id; ``pose`` None: a free place)."""

    robot_id: int | None
    pose: tuple[float, float, float] | None
    robot: RobotSpec


def parse_spawn_request(text: str, default: RobotSpec) -> SpawnRequest:
    """Parse a spawn payload (YAML mapping); raises ConfigError naming the bad field."""
    try:
        data = yaml.safe_load(text) if text.strip() else {}
    except yaml.YAMLError as exc:
        raise ConfigError.at("spawn", "malformed YAML", str(exc).splitlines()[0]) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError.at("spawn", "must be a YAML mapping", text[:80],
                             "{id: 7, pose: [x, y, yaw]}")
    allowed = {"id", "pose"} | _SPAWN_ROBOT_KEYS
    unknown = sorted(set(map(str, data)) - allowed)
    if unknown:
        raise ConfigError.at(f"spawn.{unknown[0]}", "unknown key",
                             expected=f"one of {sorted(allowed)}")
    robot_id = data.get("id")
    if robot_id is not None and (isinstance(robot_id, bool) or not isinstance(robot_id, int)
                                 or robot_id < 0):
        raise ConfigError.at("spawn.id", "must be an integer >= 0", robot_id)
    pose = data.get("pose")
    if pose is not None:
        if (not isinstance(pose, list | tuple) or len(pose) not in (2, 3)
                or not all(_is_finite_number(v) for v in pose)):
            raise ConfigError.at("spawn.pose", "must be [x, y] or [x, y, yaw] (finite numbers)",
                                 pose)
        pose = (float(pose[0]), float(pose[1]), float(pose[2]) if len(pose) == 3 else 0.0)
    overrides: dict[str, Any] = {k: v for k, v in data.items() if k in _SPAWN_ROBOT_KEYS}
    for key, value in overrides.items():
        if not _is_finite_number(value):
            raise ConfigError.at(f"spawn.{key}", "must be a finite number", value)
    return SpawnRequest(robot_id, pose, replace(default, **overrides))


def _is_finite_number(value: Any) -> bool:
    return (not isinstance(value, bool) and isinstance(value, int | float)
            and math.isfinite(value))


# ---------------------------------------------------------------------------- diagnostics
def diagnostic_status(name: str, message: str, values: dict[str, Any],
                      level: bytes = DiagnosticStatus.OK,
                      hardware_id: str = "") -> DiagnosticStatus:
    """A ``diagnostic_msgs/DiagnosticStatus`` with ``values`` as key/value strings (floats with
    6 significant digits)."""
    return DiagnosticStatus(
        level=level, name=name, message=message, hardware_id=hardware_id,
        values=[KeyValue(key=k, value=f"{v:.6g}" if isinstance(v, float) else str(v))
                for k, v in values.items()])


def diagnostic_values(status: DiagnosticStatus) -> dict[str, str]:
    """The key/value pairs of a ``DiagnosticStatus`` as a dict."""
    return {kv.key: kv.value for kv in status.values}


# ---------------------------------------------------------------------------- robot outputs
def pose_stamped_msg(stamp: Time, x: float, y: float, yaw: float,
                     frame_id: str = MAP_FRAME) -> PoseStamped:
    msg = PoseStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.pose.position.x, msg.pose.position.y = float(x), float(y)
    msg.pose.orientation = yaw_to_quaternion(yaw)
    return msg


def path_msg(stamp: Time, points: np.ndarray, frame_id: str = MAP_FRAME) -> Path:
    """``nav_msgs/Path`` through ``(M, 2)`` points, each pose heading along the path."""
    msg = Path()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    for k, (x, y) in enumerate(pts):
        nxt = pts[min(k + 1, len(pts) - 1)] - pts[max(k - 1, 0)] if len(pts) > 1 else (1.0, 0.0)
        msg.poses.append(pose_stamped_msg(stamp, x, y, math.atan2(nxt[1], nxt[0]), frame_id))
    return msg


def path_to_points(msg: Path) -> np.ndarray:
    return np.array([[p.pose.position.x, p.pose.position.y] for p in msg.poses],
                    dtype=np.float64).reshape(-1, 2)


def cell_grid_msg(grid: GridMap, nodes: np.ndarray, stamp: Time,
                  frame_id: str = MAP_FRAME) -> OccupancyGrid:
    """The cell ``nodes`` (ids ``row * W + col`` of ``grid``) as an OccupancyGrid cropped to
    their bounding box (100 in the cell, 0 elsewhere); an empty 0 x 0 grid for no cell."""
    W = grid.width
    nodes = np.asarray(nodes, dtype=np.int64)
    msg = OccupancyGrid()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.info.resolution = float(grid.resolution)
    if len(nodes) == 0:
        return msg
    rows, cols = nodes // W, nodes % W
    r0, c0 = int(rows.min()), int(cols.min())
    h, w = int(rows.max()) - r0 + 1, int(cols.max()) - c0 + 1
    data = np.zeros((h, w), dtype=np.int8)
    data[rows - r0, cols - c0] = 100
    ox, oy = grid.grid_to_world(np.array([c0, r0], dtype=np.float64))
    msg.info.width, msg.info.height = w, h
    msg.info.origin.position.x, msg.info.origin.position.y = float(ox), float(oy)
    msg.info.origin.orientation = yaw_to_quaternion(grid.origin[2])
    msg.data = array.array("b", data.tobytes())
    return msg


def polygon_msg(stamp: Time, polygon: np.ndarray, frame_id: str = MAP_FRAME) -> PolygonStamped:
    msg = PolygonStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    for x, y in np.asarray(polygon, dtype=np.float64).reshape(-1, 2):
        msg.polygon.points.append(Point32(x=float(x), y=float(y), z=0.0))
    return msg


def scan_to_points(msg: LaserScan, pose: tuple[float, float, float]) -> np.ndarray:
    """``(M, 2)`` map-frame hit points of a scan taken at robot ``pose`` (the lidar sits at
    the robot centre, axes as base_link); only finite returns within the sensor limits."""
    angles, ranges = laser_scan_to_ranges(msg)
    ok = np.isfinite(ranges) & (ranges >= msg.range_min) & (ranges <= msg.range_max)
    a = angles[ok] + pose[2]
    r = ranges[ok]
    return np.stack([pose[0] + r * np.cos(a), pose[1] + r * np.sin(a)], axis=-1)


# ---------------------------------------------------------------------------- coverage state
STATE_REQUIRED = ("x", "y")


def coverage_state_msg(stamp: Time, values: dict[str, float],
                       frame_id: str = MAP_FRAME) -> JointState:
    """``coverage_state`` message from named values (see module docstring)."""
    msg = JointState()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    names = list(values)
    msg.name = names
    msg.position = [float(values[k]) for k in names]
    return msg


def coverage_state_values(msg: JointState, expected_frame: str = MAP_FRAME) -> dict[str, float]:
    """Named values of a ``coverage_state`` message; ValueError naming the problem (wrong
    frame, missing x/y, mismatched lengths, non-finite x/y)."""
    if msg.header.frame_id != expected_frame:
        raise ValueError(f"frame_id {msg.header.frame_id!r}, expected {expected_frame!r}")
    if len(msg.name) != len(msg.position):
        raise ValueError(f"{len(msg.name)} names but {len(msg.position)} values")
    values = {str(n): float(v) for n, v in zip(msg.name, msg.position, strict=True)}
    for key in STATE_REQUIRED:
        if key not in values:
            raise ValueError(f"no {key!r} value")
        if not math.isfinite(values[key]):
            raise ValueError(f"{key} is {values[key]!r}")
    return values


# ---------------------------------------------------------------------------- viewer inputs
def pose_stamped_to_pose(msg: PoseStamped) -> tuple[float, float, float]:
    """``(x, y, yaw)`` of a ``geometry_msgs/PoseStamped``, in its header frame."""
    p = msg.pose
    return p.position.x, p.position.y, quaternion_to_yaw(p.orientation)


def polygon_to_points(msg: PolygonStamped) -> np.ndarray:
    """``(M, 2) float64`` [m] vertices of a ``geometry_msgs/PolygonStamped`` (z dropped)."""
    return np.array([[p.x, p.y] for p in msg.polygon.points], dtype=np.float64).reshape(-1, 2)


def cell_grid_to_grid(msg: OccupancyGrid) -> GridMap | None:
    """A ``cell`` grid (see module docstring) as a :class:`GridMap`, None for the empty 0 x 0
    grid of a robot without a cell; ConfigError if inconsistent."""
    if msg.info.width == 0 or msg.info.height == 0:
        return None
    return occupancy_grid_to_grid(msg)
