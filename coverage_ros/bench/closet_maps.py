"""The floor plans of the dead-end-room benchmarks (``scripts/bench_closets``, offline and
``--live``), rasterized as the benchmark scores them, and the score: H and the cell masses of a
team's positions."""

from __future__ import annotations

import dataclasses

import numpy as np

from coverage_ros.bench.environment import SHARED_MAPS
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tessellation import Generator, fast_tessellate
from coverage_ros.core.world import WorldSpec, parse_world
from coverage_ros.core.world.grid import FREE, OCCUPIED, UNKNOWN, GridMap

MAPS = {"tb3_sandbox": SHARED_MAPS / "tb3_sandbox.yaml", "depot": SHARED_MAPS / "depot.yaml",
        "warehouse": SHARED_MAPS / "warehouse.yaml", "office": "office", "ward": "ward",
        "hostel": "hostel"}
#: hostel (drawn here, not tuned on): [m] widths of the rooms below and above a corridor, and
#: where each room's door starts from its left wall.
HOSTEL_BELOW = ((3.0, 1.0), (2.0, 0.6), (4.0, 2.6), (2.5, 0.8), (4.5, 0.4))
HOSTEL_ABOVE = ((2.0, 0.5), (5.0, 3.8), (2.0, 1.0), (3.0, 0.3), (4.0, 1.5))
HOSTEL_DOOR = 0.9  # [m] door width
RESOLUTION = 0.1  # [m] benchmark raster: a restart on warehouse (30 x 50 m) in seconds
TARGET = 1.05  # H_final / H_best at most


def hostel() -> WorldSpec:
    """16 m x 9 m: a 1.2 m corridor at y 4-5.2 m, five rooms 4 m deep below it and five
    3.8 m deep above it, each with one door onto the corridor (rooms 2 m wide are closets of
    8 m^2 or less)."""
    return parse_world(hostel_plan())


def hostel_plan() -> dict:
    """:func:`hostel` as a world file's mapping."""
    walls = []

    def wall(a: tuple[float, float], b: tuple[float, float]) -> None:
        walls.append({"type": "wall", "from": list(a), "to": list(b), "thickness": 0.1})

    for y, rooms, y_far in ((4.0, HOSTEL_BELOW, 0.0), (5.2, HOSTEL_ABOVE, 9.0)):
        x = 0.0
        for width, door in rooms:
            wall((x, y), (x + door, y))
            wall((x + door + HOSTEL_DOOR, y), (x + width, y))
            x += width
            if x < 16.0:
                wall((x, y), (x, y_far))
    return {"name": "hostel", "resolution": RESOLUTION, "bounds": [0.0, 0.0, 16.0, 9.0],
            "obstacles": walls}


def coarse_world(world: WorldSpec, resolution: float) -> WorldSpec:
    """``world`` rasterized at ``resolution`` [m] when its own cells are finer: a floor plan
    (bounds and obstacles) anew, a map_server map by blocks of whole cells (occupied if any
    fine cell is, else unknown if any is, else free)."""
    if world.resolution >= resolution - 1e-12:
        return world
    if world.base_map is None:
        return dataclasses.replace(world, resolution=resolution)
    base = world.base_map
    k = max(1, int(round(resolution / base.resolution)))
    h, w = (base.shape[0] // k) * k, (base.shape[1] // k) * k
    blocks = base.occupancy[:h, :w].reshape(h // k, k, w // k, k)
    occupied = (blocks >= OCCUPIED // 2).any(axis=(1, 3))
    unknown = (blocks < 0).any(axis=(1, 3))
    occ = np.where(occupied, OCCUPIED, np.where(unknown, UNKNOWN, FREE)).astype(np.int8)
    grid = GridMap(occ, base.resolution * k, base.origin)
    return dataclasses.replace(world, resolution=grid.resolution, base_map=grid)


def score(domain: CoverageDomain, positions: np.ndarray) -> tuple[float, np.ndarray]:
    """H and the cell masses of the team at ``positions (n, 2)`` [m]."""
    tess = fast_tessellate(domain, [Generator(p) for p in positions])
    return tess.cost, tess.masses
