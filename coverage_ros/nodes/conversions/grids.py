"""Message conversions: occupancy grids (conventions: :mod:`..conversions`)."""


from __future__ import annotations

import array

import numpy as np
from builtin_interfaces.msg import Time
from nav_msgs.msg import OccupancyGrid

from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError
from coverage_ros.nodes.conversions.basics import MAP_FRAME, quaternion_to_yaw, yaw_to_quaternion


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

