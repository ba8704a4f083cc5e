"""The floor plans of the dead-end-room benchmarks (``scripts/bench_closets``, offline and
``--live``), rasterized as the benchmark scores them, and the score: H and the cell masses of a
team's positions."""

from __future__ import annotations

import dataclasses
import re

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
#: drawn plans (:func:`drawn_plan`): ``plan-<seed>``, a floor plan of random rooms per seed
DRAWN = re.compile(r"plan-(\d+)")
DRAWN_WIDTH = (14.0, 22.0)  # [m] building length along the corridor
DRAWN_CORRIDOR = (1.2, 2.0)  # [m] corridor width
DRAWN_DEPTH = (3.0, 5.0)  # [m] depth of the rooms on either side
DRAWN_ROOM = (1.5, 5.0)  # [m] room widths
#: rooms at least this wide [m] may have a closet across their back (with this chance), its
#: depth [m] drawn from DRAWN_CLOSET_DEPTH and its own door
DRAWN_CLOSET_FROM, DRAWN_CLOSET_CHANCE, DRAWN_CLOSET_DEPTH = 3.5, 0.4, (1.2, 1.8)
DRAWN_CLOSET_DOOR = 0.8  # [m]
DRAWN_ROOM_DOOR = 0.9  # [m] a room's door onto the corridor (the hostel's)
#: drawn plans of two corridors (:func:`twin_plan`): ``twin-<seed>``, their own random stream
#: and building length [m]
TWIN = re.compile(r"twin-(\d+)")
TWIN_STREAM = 2
TWIN_LENGTH = (18.0, 26.0)
RESOLUTION = 0.1  # [m] benchmark raster: a restart on warehouse (30 x 50 m) in seconds
TARGET = 1.05  # H_final / H_best at most
ROBOTS = 8  # the benchmark's team; a map run with another size is an entry of its own
#: a map's entry for a team of another size than ROBOTS (:func:`entry`)
SIZED = re.compile(r"(.+), (\d+) robots")
Wall = tuple[tuple[float, float], tuple[float, float]]  # [m] a wall's two ends


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


def drawn_plan(seed: int) -> dict:
    """Floor plan ``plan-<seed>`` as a world file's mapping, drawn from ``seed`` alone: a
    corridor along the building with rooms on both sides (widths, door places and depths at
    random), some rooms with a closet across their back behind a door of its own (rooms within
    rooms: dead ends two doors deep); on half the seeds the corridor runs along y. A plan no
    part of the stack was tuned on, as many as wanted."""
    rng = np.random.default_rng(seed)
    length = float(rng.uniform(*DRAWN_WIDTH))
    corridor = rng.uniform(*DRAWN_CORRIDOR)
    below, above = rng.uniform(*DRAWN_DEPTH, 2)
    y0, y1 = below, below + corridor
    height = float(y1 + above)
    walls: list[Wall] = []
    for y, y_far in ((y0, 0.0), (y1, height)):
        walls += _rooms(rng, 0.0, length, y, y_far)
    return _plan(f"plan-{seed}", rng, walls, length, height)


def twin_plan(seed: int) -> dict:
    """Floor plan ``twin-<seed>`` as a world file's mapping, drawn from ``seed`` alone (a
    stream of its own, not ``plan-<seed>``'s): two corridors along the building, rooms on
    their outer sides and two rows of rooms back to back between them, the middle rows broken
    by a cross corridor that joins the two; rooms, doors and closets as in
    :func:`drawn_plan`, and on half the seeds the corridors run along y."""
    rng = np.random.default_rng([TWIN_STREAM, seed])
    length = float(rng.uniform(*TWIN_LENGTH))
    corridors = rng.uniform(*DRAWN_CORRIDOR, 2)
    depths = rng.uniform(*DRAWN_DEPTH, 4)  # (outer, middle, middle, outer rows)
    cross = float(rng.uniform(*DRAWN_CORRIDOR))
    x_cross = float(rng.uniform(0.25 * length, 0.75 * length - cross))
    y_a = depths[0]  # the first corridor's near side, then its far side and so on up
    y_a1 = y_a + corridors[0]
    y_mid = y_a1 + depths[1]
    y_b = y_mid + depths[2]
    y_b1 = y_b + corridors[1]
    height = float(y_b1 + depths[3])
    walls = _rooms(rng, 0.0, length, y_a, 0.0)
    for y in (y_a1, y_b):
        walls += _rooms(rng, 0.0, x_cross, y, y_mid)
        walls += _rooms(rng, x_cross + cross, length, y, y_mid)
    walls += _rooms(rng, 0.0, length, y_b1, height)
    walls += [((0.0, y_mid), (x_cross, y_mid)), ((x_cross + cross, y_mid), (length, y_mid)),
              ((x_cross, y_a1), (x_cross, y_b)), ((x_cross + cross, y_a1), (x_cross + cross, y_b))]
    return _plan(f"twin-{seed}", rng, walls, length, height)


def _rooms(rng: np.random.Generator, x0: float, x1: float, y: float, y_far: float
           ) -> list[Wall]:
    """The walls of a row of rooms side by side over ``x0 .. x1`` between the line ``y``
    (their doors, onto a corridor) and ``y_far`` (their backs): random widths and door
    places, a closet across the back of some, a wall between neighbours (none at the row's
    ends)."""
    walls: list[Wall] = []
    x = x0
    for width in _room_widths(rng, x1 - x0):
        door = rng.uniform(0.2, width - DRAWN_ROOM_DOOR - 0.2)
        walls += [((x, y), (x + door, y)),
                  ((x + door + DRAWN_ROOM_DOOR, y), (x + width, y))]
        if width >= DRAWN_CLOSET_FROM and rng.random() < DRAWN_CLOSET_CHANCE:
            depth = rng.uniform(*DRAWN_CLOSET_DEPTH)
            yc = y_far + depth if y_far < y else y_far - depth
            at = rng.uniform(0.2, width - DRAWN_CLOSET_DOOR - 0.2)
            walls += [((x, yc), (x + at, yc)),
                      ((x + at + DRAWN_CLOSET_DOOR, yc), (x + width, yc))]
        x += width
        if x < x1 - 1e-9:
            walls.append(((x, y), (x, y_far)))
    return walls


def _plan(name: str, rng: np.random.Generator, walls: list[Wall], length: float,
          height: float) -> dict:
    """The world mapping of a drawn plan of ``walls`` in ``length`` x ``height`` [m]; turned
    a quarter (x and y swapped) on half the draws of ``rng``."""
    bounds = [0.0, 0.0, round(length, 3), round(height, 3)]  # (plain floats: a world file)
    if rng.random() < 0.5:  # (the corridor along y)
        walls = [((a[1], a[0]), (b[1], b[0])) for a, b in walls]
        bounds = [0.0, 0.0, bounds[3], bounds[2]]
    return {"name": name, "resolution": RESOLUTION, "bounds": bounds,
            "obstacles": [{"type": "wall", "from": [round(float(v), 3) for v in a],
                           "to": [round(float(v), 3) for v in b], "thickness": 0.1}
                          for a, b in walls]}


def _room_widths(rng: np.random.Generator, length: float) -> list[float]:
    """[m] widths of rooms side by side over ``length``, each within DRAWN_ROOM (the last
    takes what is left, or joins the one before when that is too narrow)."""
    widths: list[float] = []
    left = length
    while left > DRAWN_ROOM[1]:
        widths.append(min(rng.uniform(*DRAWN_ROOM), left - DRAWN_ROOM[0]))
        left -= widths[-1]
    if left >= DRAWN_ROOM[0] or not widths:
        widths.append(left)
    else:
        widths[-1] += left
    return widths


def floor_plan(name: str) -> dict | None:
    """The world mapping of a plan drawn here (``hostel``, ``plan-<seed>``,
    ``twin-<seed>``); None for the maps read from files (:data:`MAPS`)."""
    if name == "hostel":
        return hostel_plan()
    drawn, twin = DRAWN.fullmatch(name), TWIN.fullmatch(name)
    if twin:
        return twin_plan(int(twin.group(1)))
    return drawn_plan(int(drawn.group(1))) if drawn else None


def known_map(name: str) -> bool:
    """Whether ``name`` is a benchmark map: one of :data:`MAPS` or a drawn ``plan-<seed>`` or
    ``twin-<seed>``."""
    return name in MAPS or DRAWN.fullmatch(name) is not None or TWIN.fullmatch(name) is not None


def entry(name: str, robots: int) -> str:
    """The results file's key for map ``name`` with a team of ``robots``: the name for the
    benchmark's own team (:data:`ROBOTS`), else ``"<name>, <robots> robots"`` (each size has
    its own restarts, best known H and rows)."""
    return name if robots == ROBOTS else f"{name}, {robots} robots"


def entry_map(key: str) -> tuple[str, int]:
    """The map and team size of a results file's key (:func:`entry`)."""
    sized = SIZED.fullmatch(key)
    return (sized.group(1), int(sized.group(2))) if sized else (key, ROBOTS)


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
