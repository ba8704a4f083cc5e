"""Simulated planar range scans on an occupancy grid (for offline runs of sensor-based
strategies; the world node's lidar, in :mod:`coverage_ros.sim`, casts against exact geometry).

Beams march through the grid in steps of a third of a cell; a beam ends at the first sample in
an occupied (or unknown, or off-map) cell, or at a disc of another robot (exact ray-circle
intersection). Ranges follow REP 117: ``inf`` where nothing is hit within ``range_max``.
"""

from __future__ import annotations

import numpy as np

from coverage_ros.core.strategies.base import Scan
from coverage_ros.core.world import LidarSpec
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.robot import TB3_RADIUS

#: Ray-marching step as a fraction of a cell: the range error is below this many cells.
STEP_CELLS = 1.0 / 3.0


def simulate_scan(grid: GridMap, pose: np.ndarray, lidar: LidarSpec,
                  others: np.ndarray | None = None, other_radii: np.ndarray | None = None,
                  blocked: np.ndarray | None = None) -> Scan:
    """A scan from ``pose (x, y, yaw)``; ``others (M, 2)`` are other robots' centres with
    radii ``other_radii (M,)``; ``blocked`` overrides the grid's occupied mask."""
    blocked = grid.occupied_mask() if blocked is None else blocked
    x, y, yaw = (float(v) for v in pose)
    angles = yaw + lidar.angle_min + lidar.angle_increment * np.arange(lidar.beams)
    step = STEP_CELLS * grid.resolution
    t = np.arange(lidar.range_min, lidar.range_max + step, step)
    dx, dy = np.cos(angles), np.sin(angles)
    px = x + dx[:, None] * t[None, :]
    py = y + dy[:, None] * t[None, :]
    cells = grid.world_to_cell(np.stack([px.ravel(), py.ravel()], axis=-1))
    inside = grid.contains_cell(cells)
    hit = np.ones(len(cells), dtype=bool)
    hit[inside] = blocked[cells[inside, 0], cells[inside, 1]]
    hit = hit.reshape(px.shape)
    first = np.argmax(hit, axis=1)
    ranges = np.where(hit.any(axis=1), t[first], np.inf)
    if others is not None and len(others):
        others = np.asarray(others, dtype=np.float64).reshape(-1, 2)
        radii = np.broadcast_to(np.asarray(other_radii if other_radii is not None else TB3_RADIUS,
                                           dtype=np.float64), (len(others),))
        # |o + s d - c|^2 = r^2 with |d| = 1: s = b -/+ sqrt(b^2 - (|o - c|^2 - r^2)).
        ox, oy = others[:, 0] - x, others[:, 1] - y
        b = dx[:, None] * ox[None, :] + dy[:, None] * oy[None, :]
        c = (ox * ox + oy * oy - radii * radii)[None, :]
        disc = b * b - c
        with np.errstate(invalid="ignore"):
            s = b - np.sqrt(disc)
        s = np.where((disc >= 0) & (s >= lidar.range_min), s, np.inf)
        ranges = np.minimum(ranges, s.min(axis=1))
    ranges = np.where(ranges <= lidar.range_max, ranges, np.inf)
    return Scan(ranges=ranges, angle_min=lidar.angle_min, angle_increment=lidar.angle_increment,
                range_min=lidar.range_min, range_max=lidar.range_max)

