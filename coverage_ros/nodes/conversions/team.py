"""Message conversions: spawn requests and a robot's outputs (conventions:
:mod:`..conversions`)."""


from __future__ import annotations

import array
import math
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
import yaml
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point32, PolygonStamped, PoseStamped
from nav_msgs.msg import OccupancyGrid, Path
from sensor_msgs.msg import LaserScan

from coverage_ros.core.world import RobotSpec
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError
from coverage_ros.nodes.conversions.basics import MAP_FRAME, quaternion_to_yaw, yaw_to_quaternion
from coverage_ros.nodes.conversions.grids import occupancy_grid_to_grid
from coverage_ros.nodes.conversions.motion import laser_scan_to_ranges

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
