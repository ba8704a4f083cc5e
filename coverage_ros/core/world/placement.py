"""Where a robot may stand: the one place that answers it for the simulator, the launcher and
the planner.

* :func:`clearance` - [m] from a point to the nearest obstacle, arena wall or blocked map cell;
* :func:`check_pose` - a pose a robot of a given radius may take (on the map, clear of walls by
  its radius, not overlapping robots already there), else a :class:`WorldError` naming it;
* :func:`validate_starts` - the same for a list of start poses;
* :func:`cluster_starts` - a seeded compact hexagonal cluster in the largest free region (the
  robots must spread from it); :class:`FreePlacer` - random free poses (spawning);
* :func:`parse_poses` - ``"x,y,yaw;..."`` as typed on a command line;
* :func:`team_starts` - the start poses of a team, as the launcher and the planner choose them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from coverage_ros.core.geodesic.graph import build_grid_graph
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.errors import ConfigError, WorldError

CLUSTER_GAP = 0.12  # [m] free space between neighbouring robots of a start cluster
CLUSTER_WALL_MARGIN = 0.05  # [m] extra distance from walls for cluster start positions
PLACEMENT_TRIES = 500  # random free cells tried before giving up (each try is a cheap check)
#: [m] how far around a point blocked map cells are looked for (beyond it: "far enough" for
#: any robot radius).
MAP_CLEARANCE_REACH = 1.0

Pose = tuple[float, float, float]
Disc = tuple[float, float, float]  # (x [m], y [m], radius [m]) of a robot present


def clearance(spec: WorldSpec, x: float, y: float) -> float:
    """[m] distance from a point to the nearest obstacle, wall or blocked map cell (0 inside
    one), from the exact obstacle geometry (not the raster)."""
    p = np.array([[x, y]])
    best = math.inf
    if spec.bounds is not None:
        xmin, ymin, xmax, ymax = spec.bounds
        best = min(best, x - xmin, xmax - x, y - ymin, ymax - y)
    for obs in spec.obstacles:
        best = min(best, float(obs.distance(p)[0]))
    if spec.base_map is not None:
        best = min(best, _blocked_square_distance(spec.base_map, x, y, MAP_CLEARANCE_REACH))
    return max(best, 0.0)


def check_pose(spec: WorldSpec, pose: Sequence[float], radius: float,
               others: Sequence[Disc] = (), where: str = "pose") -> Pose:
    """``pose`` ``(x, y, yaw)`` if a robot of ``radius`` [m] may stand there: on the map, at
    least ``radius`` from every wall and obstacle, not overlapping any of ``others``. Raises
    :class:`WorldError` naming ``where`` otherwise."""
    if len(pose) != 3 or not all(math.isfinite(float(v)) for v in pose):
        raise WorldError.at(where, "must be three finite numbers [x, y, yaw]", tuple(pose))
    x, y, yaw = (float(v) for v in pose)
    grid = spec.grid
    if not grid.contains_point(np.array([[x, y]]))[0]:
        xmin, ymin, xmax, ymax = grid.extent()
        raise WorldError.at(where, "start is outside the map", (x, y),
                            f"x in [{xmin:g}, {xmax:g}], y in [{ymin:g}, {ymax:g}]")
    room = clearance(spec, x, y)
    if room < radius:
        raise WorldError.at(where, f"start ({x:g}, {y:g}) is inside an obstacle or wall "
                            f"(clearance {room:.3f} m < robot radius {radius:g} m)")
    for ox, oy, r in others:
        if math.hypot(x - ox, y - oy) < radius + r:
            raise WorldError.at(where, f"start ({x:g}, {y:g}) overlaps the robot at "
                                f"({ox:g}, {oy:g})")
    return (x, y, yaw)


def validate_starts(spec: WorldSpec, starts: Sequence[Sequence[float]] | np.ndarray,
                    radii: Sequence[float], where: str = "robots") -> None:
    """Raise if a start pose ``(x, y[, yaw])`` of robot i (radius ``radii[i]``) is off the map,
    too close to an obstacle, or overlaps an earlier robot."""
    placed: list[Disc] = []
    for i, (start, radius) in enumerate(zip(starts, radii, strict=True)):
        pose = (*start, 0.0) if len(start) == 2 else tuple(start)
        x, y, _ = check_pose(spec, pose, radius, placed, f"{where}[{i}]")
        placed.append((x, y, radius))


def _blocked_square_distance(grid: GridMap, x: float, y: float, reach: float) -> float:
    """[m] distance from (x, y) to the nearest blocked cell square within ``reach`` (inf if none;
    outside the grid counts as blocked)."""
    g = grid.world_to_grid(np.array([x, y]))
    res = grid.resolution
    if not grid.contains_point(np.array([[x, y]]))[0]:
        return 0.0
    n = int(math.ceil(reach / res)) + 1
    c0, r0 = int(math.floor(g[0])), int(math.floor(g[1]))
    rows = np.arange(r0 - n, r0 + n + 1)
    cols = np.arange(c0 - n, c0 + n + 1)
    R, C = np.meshgrid(rows, cols, indexing="ij")
    inside = (R >= 0) & (R < grid.height) & (C >= 0) & (C < grid.width)
    blocked = np.ones(R.shape, dtype=bool)
    occ = grid.occupied_mask()
    blocked[inside] = occ[R[inside], C[inside]]
    if not blocked.any():
        return math.inf
    # Distance in grid units from the point to each blocked unit square [c, c+1] x [r, r+1].
    dx = np.maximum(np.maximum(C - g[0], g[0] - (C + 1)), 0.0)
    dy = np.maximum(np.maximum(R - g[1], g[1] - (R + 1)), 0.0)
    return float(np.hypot(dx, dy)[blocked].min() * res)


def largest_free_region(grid: GridMap, radius: float) -> np.ndarray:
    """``(H, W) bool``: the cells of the largest 8-connected region where a robot of ``radius``
    [m] keeps ``CLUSTER_WALL_MARGIN`` from walls (all False if there is none)."""
    free = grid.inflated_free_mask(radius + CLUSTER_WALL_MARGIN)
    from scipy import ndimage  # scipy's import is a tenth of a second: only when used

    labels, n = ndimage.label(free, structure=np.ones((3, 3)))
    if n == 0:
        return np.zeros(grid.shape, dtype=bool)
    largest: np.ndarray = labels == (int(np.argmax(np.bincount(labels.ravel())[1:])) + 1)
    return largest


def parse_poses(text: str, where: str = "starts") -> np.ndarray:
    """``"x,y;x,y"`` or ``"x,y,yaw;..."`` -> ``(n, 3)`` poses (yaw 0 when omitted)."""
    rows = []
    for k, item in enumerate(s for s in text.split(";") if s.strip()):
        try:
            vals = [float(v) for v in item.split(",")]
        except ValueError:
            raise ConfigError.at(f"{where}[{k}]", "must be numbers 'x,y' or 'x,y,yaw'",
                                 item) from None
        if len(vals) not in (2, 3) or not all(math.isfinite(v) for v in vals):
            raise ConfigError.at(f"{where}[{k}]", "must be 'x,y' or 'x,y,yaw' (finite)", item)
        rows.append(vals + [0.0] * (3 - len(vals)))
    if not rows:
        raise ConfigError.at(where, "no pose given", text, "'x,y;x,y;...'")
    return np.array(rows)


def check_free_area(world: WorldSpec, robots: int, radius: float, where: str = "--robots",
                    radius_where: str = "--robot-radius") -> None:
    """Refuse more robots than ``world``'s free area holds at their radius and spacing
    (hexagonal packing, :data:`CLUSTER_GAP` apart), naming the options ``where`` (the team
    size) and ``radius_where`` (the radius, when no free space is wide enough for one)."""
    free = world.grid.inflated_free_mask(radius)
    area = float(free.sum()) * world.grid.resolution ** 2
    if area == 0.0:
        raise ConfigError.at(radius_where, f"{world.name} has no free space wide enough for a "
                             "robot of this radius", radius)
    spacing = 2.0 * radius + CLUSTER_GAP
    per_robot = spacing * spacing * math.sqrt(3.0) / 2.0
    if robots * per_robot > area:
        raise ConfigError.at(where, f"{robots} robots of radius {radius:g} m need about "
                             f"{robots * per_robot:.1f} m^2 packed {CLUSTER_GAP:g} m apart; "
                             f"{world.name} has {area:.1f} m^2 of free space for them",
                             expected=f"at most {int(area // per_robot)}")


def team_starts(world: WorldSpec, specs: Sequence[RobotSpec], starts: str | None, seed: int,
                where: str = "--starts") -> np.ndarray:
    """``(n, 3)`` start poses of a team of robots ``specs``: the poses typed in ``starts``
    (``"x,y[,yaw];..."``, checked), else the world's own start poses when it lists one for
    every robot, else a compact cluster seeded by ``seed`` (so the robots must spread)."""
    n = len(specs)
    radii = [s.radius for s in specs]
    if starts:
        poses = parse_poses(starts, where)
        if len(poses) != n:
            raise ConfigError.at(where, f"gives {len(poses)} poses for {n} robots", starts)
        validate_starts(world, poses, radii, where)
        return poses
    if len(world.starts) >= n:
        return np.array([[s.x, s.y, s.yaw] for s in world.starts[:n]])
    return cluster_starts(world.grid, n, max(radii), np.random.default_rng(seed))


def cluster_starts(grid: GridMap, count: int, radius: float, rng: np.random.Generator,
                   gap: float = CLUSTER_GAP) -> np.ndarray:
    """``(count, 3)`` poses ``(x, y, yaw)`` packed in a compact hexagonal cluster.

    The cluster centre is a random free cell of the largest connected free region (so the
    robots can spread over the main area); positions are the hexagonal lattice points
    (spacing ``2 * radius + gap``) nearest to it *along free paths*, so a cluster never
    straddles a wall.
    """
    if count < 1:
        raise ConfigError.at("num_robots", "must be >= 1", count)
    region = largest_free_region(grid, radius)
    if not region.any():
        raise WorldError.at("num_robots", "the map has no free space wide enough for a robot "
                            f"of radius {radius:g} m")
    spacing = 2.0 * radius + gap
    res = grid.resolution
    # Prefer seeds with room around them: clearance of at least a third of the cluster radius.
    need = 0.5 * spacing * math.sqrt(count) / 3.0
    roomy = region & (grid.clearance() > need)
    pool = np.flatnonzero((roomy if roomy.any() else region).ravel())
    seed_cell = np.array(np.unravel_index(int(rng.choice(pool)), grid.shape))
    # Geodesic (8-connected) distance from the seed over the region, via a chamfer BFS bounded
    # to a window large enough for the cluster.
    reach_cells = int(math.ceil((spacing * (math.sqrt(count) + 2.0) * 2.0) / res)) + 2
    r0, c0 = np.maximum(seed_cell - reach_cells, 0)
    r1 = min(seed_cell[0] + reach_cells + 1, grid.height)
    c1 = min(seed_cell[1] + reach_cells + 1, grid.width)
    window = region[r0:r1, c0:c1]
    dist = _grid_geodesic(window, (seed_cell[0] - r0, seed_cell[1] - c0)) * res
    center = grid.cell_centers(seed_cell[None])[0]
    k = int(math.ceil(reach_cells * res / spacing)) + 1
    a, b = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1), indexing="ij")
    lattice = np.stack([a + 0.5 * b, b * math.sqrt(3.0) / 2.0], axis=-1).reshape(-1, 2) * spacing
    pts = center + lattice
    cells = grid.world_to_cell(pts) - np.array([r0, c0])
    ok = ((cells[:, 0] >= 0) & (cells[:, 0] < window.shape[0])
          & (cells[:, 1] >= 0) & (cells[:, 1] < window.shape[1]))
    pts, cells = pts[ok], cells[ok]
    d = dist[cells[:, 0], cells[:, 1]]
    ok = np.isfinite(d)
    if ok.sum() < count:
        raise WorldError.at("num_robots", f"no room for a cluster of {count} robots near "
                            f"({center[0]:.2f}, {center[1]:.2f})", count)
    pts, d = pts[ok], d[ok]
    order = np.lexsort((np.hypot(*(pts - center).T), d))[:count]
    yaw = rng.uniform(-math.pi, math.pi, size=count)
    return np.column_stack([pts[order], yaw])


def _grid_geodesic(free: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` 8-connected shortest-path lengths [cells] from ``start`` over ``free``."""
    graph = build_grid_graph(free, 1.0, connectivity=8)
    from scipy.sparse.csgraph import dijkstra

    d: np.ndarray = dijkstra(graph.csr, indices=int(graph.node_of_cell(np.array(start))))
    return d.reshape(free.shape)


class FreePlacer:
    """Random free poses in the largest connected free region (robots spawned at run time)."""

    def __init__(self, spec: WorldSpec) -> None:
        self.spec = spec
        self._pools: dict[float, np.ndarray] = {}

    def _pool(self, radius: float) -> np.ndarray:
        """``(K, 2)`` [m] centres of free cells, in the largest region, for this radius."""
        pool = self._pools.get(radius)
        if pool is None:
            grid = self.spec.grid
            pool = grid.cell_centers(np.argwhere(largest_free_region(grid, radius)))
            self._pools[radius] = pool
        return pool

    def place(self, radius: float, others: Sequence[Disc], rng: np.random.Generator) -> Pose:
        """A random free pose for a robot of ``radius`` [m], at least ``CLUSTER_GAP`` from the
        robots ``others``; raises :class:`WorldError` if none is found."""
        pool = self._pool(radius)
        if len(pool):
            picks = pool[rng.integers(0, len(pool), size=PLACEMENT_TRIES)]
            yaws = rng.uniform(-math.pi, math.pi, size=PLACEMENT_TRIES)
            ok: np.ndarray = np.ones(PLACEMENT_TRIES, dtype=bool)
            if others:
                o = np.asarray(others, dtype=np.float64)
                d = np.hypot(picks[:, None, 0] - o[:, 0], picks[:, None, 1] - o[:, 1])
                ok = np.asarray((d >= o[:, 2] + radius + CLUSTER_GAP).all(axis=1))
            for k in np.flatnonzero(ok):
                x, y = float(picks[k, 0]), float(picks[k, 1])
                if clearance(self.spec, x, y) >= radius:
                    return (x, y, float(yaws[k]))
        raise WorldError.at("spawn", f"no free place found for a robot of radius {radius:g} m "
                            f"after {PLACEMENT_TRIES} tries")
