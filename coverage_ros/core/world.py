"""World descriptions: the package's world YAML, or a plain map_server map.

A world YAML (see ``config/worlds/*.yaml`` and README "World files")::

    name: office
    resolution: 0.05            # [m] raster of /map and of the coverage grid
    bounds: [0, 0, 12, 8]       # [xmin, ymin, xmax, ymax]; walled arena
    map: some_map.yaml          # optional map_server map, relative to this file
    robot: {radius: 0.105}      # optional defaults for every robot (TurtleBot3 Burger otherwise)
    lidar: {beams: 360}         # optional lidar defaults
    obstacles:
      - {type: box, center: [3, 2], size: [1, 0.5], yaw: 0.3}
      - {type: polygon, points: [[0, 0], [1, 0], [0, 1]]}
      - {type: circle, center: [5, 5], radius: 0.4}
      - {type: wall, from: [0, 4], to: [6, 4], thickness: 0.1}
    robots:                     # optional start poses [x, y, yaw], or mappings with overrides
      - [1.0, 1.0, 0.0]
      - {pose: [2.0, 1.0, 0.0], radius: 0.15, v_max: 0.3}
    density: {type: gaussian_mixture, components: [{mean: [8, 6], sigma: 1.0}]}

Everything is validated when loaded; errors name the file and the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from coverage_ros.core.density import Density, UniformDensity, parse_density
from coverage_ros.core.geometry import (
    box_polygon,
    distance_to_segments,
    points_in_polygon,
    polygon_edges,
    segment_polygon,
)
from coverage_ros.core.grid import FREE, OCCUPIED, GridMap
from coverage_ros.core.maps import grid_from_map_yaml, is_map_server_yaml, read_yaml_mapping
from coverage_ros.errors import ConfigError, WorldError

# TurtleBot3 Burger defaults (ROBOTIS e-Manual specifications, and nav2's tb3 DWB limits for the
# accelerations).
TB3_RADIUS = 0.105  # [m] footprint radius
TB3_V_MAX = 0.22  # [m/s] maximum linear speed
TB3_W_MAX = 2.84  # [rad/s] maximum angular speed
TB3_A_MAX = 2.5  # [m/s^2] linear acceleration limit (nav2 tb3 acc_lim_x)
TB3_ALPHA_MAX = 3.2  # [rad/s^2] angular acceleration limit (nav2 tb3 acc_lim_theta)
# LDS-01 lidar defaults.
LDS_BEAMS = 360
LDS_RANGE_MIN = 0.12  # [m]
LDS_RANGE_MAX = 3.5  # [m]
LDS_RATE_HZ = 5.0  # [Hz]

DEFAULT_RESOLUTION = 0.05  # [m] raster of worlds without a map (nav2 maps' usual resolution)
CLUSTER_GAP = 0.12  # [m] free space between neighbouring robots of a start cluster
CLUSTER_WALL_MARGIN = 0.05  # [m] extra distance from walls for cluster start positions


def _where(source: str, fieldname: str) -> str:
    return f"{source}: {fieldname}" if source else fieldname


@dataclass(frozen=True)
class LidarSpec:
    """A planar lidar (defaults: LDS-01 on the TurtleBot3)."""

    beams: int = LDS_BEAMS
    range_min: float = LDS_RANGE_MIN  # [m]
    range_max: float = LDS_RANGE_MAX  # [m]
    rate_hz: float = LDS_RATE_HZ  # [Hz] scans per second
    noise_std: float = 0.0  # [m] Gaussian range noise
    fov: float = 2.0 * math.pi  # [rad] field of view, centred on the robot's heading

    def __post_init__(self) -> None:
        if not isinstance(self.beams, int) or isinstance(self.beams, bool) or self.beams < 1:
            raise ConfigError.at("lidar.beams", "must be an integer >= 1", self.beams)
        if not 0 <= self.range_min < self.range_max or not math.isfinite(self.range_max):
            raise ConfigError.at("lidar.range_min/range_max",
                                 "need 0 <= range_min < range_max < inf",
                                 (self.range_min, self.range_max))
        if not self.rate_hz > 0:
            raise ConfigError.at("lidar.rate_hz", "must be > 0", self.rate_hz)
        if not self.noise_std >= 0:
            raise ConfigError.at("lidar.noise_std", "must be >= 0", self.noise_std)
        if not 0 < self.fov <= 2.0 * math.pi + 1e-9:
            raise ConfigError.at("lidar.fov", "must be in (0, 2*pi]", self.fov)

    @property
    def angle_increment(self) -> float:
        """[rad] between beams (a full circle does not repeat its first beam)."""
        full = self.fov >= 2.0 * math.pi - 1e-9
        return self.fov / (self.beams if full else max(self.beams - 1, 1))

    @property
    def angle_min(self) -> float:
        return -0.5 * self.fov if self.fov < 2.0 * math.pi - 1e-9 else -math.pi


@dataclass(frozen=True)
class RobotSpec:
    """Body and limits of one differential-drive robot (defaults: TurtleBot3 Burger)."""

    radius: float = TB3_RADIUS  # [m]
    v_max: float = TB3_V_MAX  # [m/s]
    w_max: float = TB3_W_MAX  # [rad/s]
    a_max: float = TB3_A_MAX  # [m/s^2]
    alpha_max: float = TB3_ALPHA_MAX  # [rad/s^2]
    lidar: LidarSpec = field(default_factory=LidarSpec)

    def __post_init__(self) -> None:
        for name in ("radius", "v_max", "w_max", "a_max", "alpha_max"):
            value = getattr(self, name)
            if (isinstance(value, bool) or not isinstance(value, int | float)
                    or not math.isfinite(value) or value <= 0):
                raise ConfigError.at(f"robot.{name}", "must be a finite number > 0", value)


@dataclass(frozen=True)
class Obstacle:
    """A static obstacle: a polygon (boxes and walls become polygons) or a circle."""

    kind: str  # "box" | "polygon" | "wall" | "circle"
    polygon: np.ndarray | None = None  # (M, 2) [m], counter-clockwise or not
    center: np.ndarray | None = None  # (2,) [m] circles only
    radius: float = 0.0  # [m] circles only

    def bounding_box(self) -> tuple[float, float, float, float]:
        if self.polygon is not None:
            lo, hi = self.polygon.min(axis=0), self.polygon.max(axis=0)
            return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])
        assert self.center is not None
        c, r = self.center, self.radius
        return float(c[0] - r), float(c[1] - r), float(c[0] + r), float(c[1] + r)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """``(N,)`` [m] distance from points to the obstacle (0 inside)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if self.polygon is not None:
            a, b = polygon_edges(self.polygon)
            d = distance_to_segments(pts, a, b)
            return np.where(points_in_polygon(pts, self.polygon), 0.0, d)
        assert self.center is not None
        return np.maximum(np.hypot(*(pts - self.center).T) - self.radius, 0.0)


@dataclass(frozen=True)
class StartPose:
    x: float
    y: float
    yaw: float
    robot: RobotSpec


@dataclass(frozen=True)
class WorldSpec:
    """A validated world; :attr:`grid` is its true occupancy raster (what ``/map`` shows)."""

    name: str
    source: str  # the file it came from ("" if built in code)
    resolution: float
    bounds: tuple[float, float, float, float] | None  # walled arena, or None
    base_map: GridMap | None
    obstacles: tuple[Obstacle, ...] = ()
    starts: tuple[StartPose, ...] = ()
    density: Density = field(default_factory=UniformDensity)
    robot: RobotSpec = field(default_factory=RobotSpec)  # default for robots without a start

    @cached_property
    def grid(self) -> GridMap:
        """The true world as an occupancy grid (obstacles 100, free 0, map unknowns kept)."""
        return rasterize_world(self)

    def robot_spec(self, index: int) -> RobotSpec:
        """The spec of robot ``index`` (its start entry's, else the world default)."""
        return self.starts[index].robot if index < len(self.starts) else self.robot

    def start_clearance(self, x: float, y: float) -> float:
        """[m] distance from a point to the nearest obstacle, wall or blocked map cell
        (0 inside one)."""
        p = np.array([[x, y]])
        best = math.inf
        if self.bounds is not None:
            xmin, ymin, xmax, ymax = self.bounds
            best = min(best, x - xmin, xmax - x, y - ymin, ymax - y)
        for obs in self.obstacles:
            best = min(best, float(obs.distance(p)[0]))
        if self.base_map is not None:
            best = min(best, _blocked_square_distance(self.base_map, x, y, reach=1.0))
        return max(best, 0.0)


# ---------------------------------------------------------------------------- rasterisation
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


def rasterize_world(spec: WorldSpec) -> GridMap:
    """A cell is occupied if an obstacle comes within half a cell of its centre, or the cell
    centre lies outside the arena bounds."""
    res = spec.resolution
    if spec.base_map is not None:
        base = spec.base_map
        occ = base.occupancy.astype(np.int8).copy()
        grid = base
    else:
        assert spec.bounds is not None
        xmin, ymin, xmax, ymax = spec.bounds
        # One ring of wall cells around the arena so /map shows its boundary.
        width = int(math.ceil((xmax - xmin) / res - 1e-9)) + 2
        height = int(math.ceil((ymax - ymin) / res - 1e-9)) + 2
        occ = np.full((height, width), FREE, dtype=np.int8)
        grid = GridMap(occ.copy(), res, (xmin - res, ymin - res, 0.0))
    X, Y = grid.all_cell_centers()
    if spec.bounds is not None:
        xmin, ymin, xmax, ymax = spec.bounds
        outside = (X < xmin) | (X > xmax) | (Y < ymin) | (Y > ymax)
        occ[outside] = OCCUPIED
    half = 0.5 * res
    for obs in spec.obstacles:
        bx0, by0, bx1, by1 = obs.bounding_box()
        sel = (X >= bx0 - res) & (X <= bx1 + res) & (Y >= by0 - res) & (Y <= by1 + res)
        if not sel.any():
            continue
        pts = np.stack([X[sel], Y[sel]], axis=-1)
        hit = obs.distance(pts) <= half
        idx = np.flatnonzero(sel.ravel())[hit]
        occ.ravel()[idx] = OCCUPIED
    return grid.with_occupancy(occ)


# ---------------------------------------------------------------------------- parsing
_WORLD_KEYS = {"name", "description", "resolution", "bounds", "map", "obstacles", "robots",
               "robot", "lidar", "density"}
_OBSTACLE_KEYS = {
    "box": {"type", "center", "size", "yaw"},
    "polygon": {"type", "points"},
    "circle": {"type", "center", "radius"},
    "wall": {"type", "from", "to", "thickness"},
}
_ROBOT_KEYS = {f.name for f in fields(RobotSpec)}
_LIDAR_KEYS = {f.name for f in fields(LidarSpec)}


def _num(where: str, value: Any, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise WorldError.at(where, "must be a finite number", value)
    if positive and value <= 0:
        raise WorldError.at(where, "must be > 0", value)
    return float(value)


def _vec(where: str, value: Any, n: int) -> np.ndarray:
    if not isinstance(value, list | tuple) or len(value) != n:
        raise WorldError.at(where, f"must be a list of {n} numbers", value)
    return np.array([_num(f"{where}[{i}]", v) for i, v in enumerate(value)])


def _check_keys(where: str, data: dict, allowed: set[str]) -> None:
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise WorldError.at(_join(where, unknown[0]), "unknown key",
                            expected=f"one of {sorted(allowed)}")


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where and not where.endswith(": ") else f"{where}{key}"


def _parse_lidar(where: str, data: Any, base: LidarSpec) -> LidarSpec:
    if not isinstance(data, dict):
        raise WorldError.at(where, "must be a mapping of lidar settings", data)
    _check_keys(where, data, _LIDAR_KEYS)
    values = {}
    for key, value in data.items():
        if key == "beams":
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise WorldError.at(_join(where, key), "must be an integer >= 1", value)
            values[key] = value
        else:
            values[key] = _num(_join(where, key), value)
    try:
        return replace(base, **values)
    except ConfigError as exc:
        raise WorldError(f"{where}: {exc}") from None


def _parse_robot(where: str, data: Any, base: RobotSpec) -> RobotSpec:
    if not isinstance(data, dict):
        raise WorldError.at(where, "must be a mapping of robot settings", data)
    _check_keys(where, data, _ROBOT_KEYS)
    values: dict[str, Any] = {}
    for key, value in data.items():
        if key == "lidar":
            values[key] = _parse_lidar(_join(where, key), value, base.lidar)
        else:
            values[key] = _num(_join(where, key), value, positive=True)
    return replace(base, **values)


def _parse_obstacle(where: str, data: Any) -> Obstacle:
    if not isinstance(data, dict) or "type" not in data:
        raise WorldError.at(where, "must be a mapping with a 'type'", data,
                            f"type one of {sorted(_OBSTACLE_KEYS)}")
    kind = data["type"]
    if kind not in _OBSTACLE_KEYS:
        raise WorldError.at(_join(where, "type"), "unknown obstacle type", kind,
                            f"one of {sorted(_OBSTACLE_KEYS)}")
    _check_keys(where, data, _OBSTACLE_KEYS[kind])
    if kind == "box":
        size = _vec(_join(where, "size"), data.get("size"), 2)
        if np.any(size <= 0):
            raise WorldError.at(_join(where, "size"), "both sides must be > 0", data["size"])
        poly = box_polygon(_vec(_join(where, "center"), data.get("center"), 2), size,
                           _num(_join(where, "yaw"), data.get("yaw", 0.0)))
        return Obstacle("box", polygon=poly)
    if kind == "polygon":
        pts = data.get("points")
        if not isinstance(pts, list) or len(pts) < 3:
            raise WorldError.at(_join(where, "points"), "need at least 3 [x, y] points", pts)
        poly = np.array([_vec(f"{_join(where, 'points')}[{i}]", p, 2) for i, p in enumerate(pts)])
        if abs(_shoelace(poly)) < 1e-12:
            raise WorldError.at(_join(where, "points"), "polygon has zero area", pts)
        return Obstacle("polygon", polygon=poly)
    if kind == "circle":
        return Obstacle("circle", center=_vec(_join(where, "center"), data.get("center"), 2),
                        radius=_num(_join(where, "radius"), data.get("radius"), positive=True))
    start = _vec(_join(where, "from"), data.get("from"), 2)
    end = _vec(_join(where, "to"), data.get("to"), 2)
    thickness = _num(_join(where, "thickness"), data.get("thickness", 0.1), positive=True)
    if np.allclose(start, end):
        raise WorldError.at(where, "wall 'from' and 'to' must differ", data)
    return Obstacle("wall", polygon=segment_polygon(start, end, thickness))


def _shoelace(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _parse_start(where: str, data: Any, base: RobotSpec) -> StartPose:
    if isinstance(data, list | tuple):
        pose, spec = data, base
    elif isinstance(data, dict):
        if "pose" not in data:
            raise WorldError.at(where, "robot entry needs a 'pose: [x, y, yaw]'", data)
        rest = {k: v for k, v in data.items() if k != "pose"}
        pose = data["pose"]
        spec = _parse_robot(where, rest, base) if rest else base
    else:
        raise WorldError.at(where, "must be [x, y, yaw] or a mapping with 'pose'", data)
    if isinstance(pose, list | tuple) and len(pose) == 2:
        pose = [*pose, 0.0]
    x, y, yaw = _vec(_join(where, "pose") if isinstance(data, dict) else where, pose, 3)
    return StartPose(float(x), float(y), float(yaw), spec)


def load_world(path: str | Path) -> WorldSpec:
    """Load a package world YAML or a map_server YAML (a world of that map alone)."""
    path = Path(path)
    data = read_yaml_mapping(path)
    if is_map_server_yaml(data):
        base = grid_from_map_yaml(path, data)
        return WorldSpec(name=path.stem, source=str(path), resolution=base.resolution,
                         bounds=None, base_map=base)
    return parse_world(data, source=str(path), base_dir=path.parent, default_name=path.stem)


def parse_world(data: dict[str, Any], source: str = "", base_dir: Path | None = None,
                default_name: str = "world") -> WorldSpec:
    """Validate a parsed world mapping (see module docstring) and build the spec."""
    def w(key: str) -> str:
        return _where(source, key)

    _check_keys(f"{source}: " if source else "", data, _WORLD_KEYS)
    name = data.get("name", default_name)
    if not isinstance(name, str) or not name:
        raise WorldError.at(w("name"), "must be a non-empty string", name)
    base_map = None
    if "map" in data:
        ref = data["map"]
        if not isinstance(ref, str) or not ref:
            raise WorldError.at(w("map"), "must be the path of a map_server YAML", ref)
        map_path = Path(ref)
        if not map_path.is_absolute():
            map_path = (base_dir or Path.cwd()) / map_path
        map_data = read_yaml_mapping(map_path)
        if not is_map_server_yaml(map_data):
            raise WorldError.at(w("map"), "is not a map_server YAML (no 'image' key)", ref)
        base_map = grid_from_map_yaml(map_path, map_data)
    default_res = base_map.resolution if base_map is not None else DEFAULT_RESOLUTION
    resolution = _num(w("resolution"), data.get("resolution", default_res), positive=True)
    if base_map is not None and not math.isclose(resolution, base_map.resolution):
        raise WorldError.at(w("resolution"), "must equal the map's resolution when 'map' is set",
                            resolution, str(base_map.resolution))
    bounds = None
    if "bounds" in data:
        b = _vec(w("bounds"), data["bounds"], 4)
        if not (b[0] < b[2] and b[1] < b[3]):
            raise WorldError.at(w("bounds"), "need xmin < xmax and ymin < ymax", data["bounds"])
        if (b[2] - b[0]) / resolution * (b[3] - b[1]) / resolution > 2.5e7:
            raise WorldError.at(w("bounds"), "arena too large for the resolution (> 25M cells)",
                                data["bounds"])
        bounds = (float(b[0]), float(b[1]), float(b[2]), float(b[3]))
    elif base_map is None:
        raise WorldError.at(w("bounds"), "required when no 'map' is given",
                            expected="[xmin, ymin, xmax, ymax]")
    robot = RobotSpec()
    if "robot" in data:
        robot = _parse_robot(w("robot"), data["robot"], robot)
    if "lidar" in data:
        robot = replace(robot, lidar=_parse_lidar(w("lidar"), data["lidar"], robot.lidar))
    obstacles_data = data.get("obstacles", []) or []
    if not isinstance(obstacles_data, list):
        raise WorldError.at(w("obstacles"), "must be a list", obstacles_data)
    obstacles = tuple(_parse_obstacle(w(f"obstacles[{i}]"), o)
                      for i, o in enumerate(obstacles_data))
    robots_data = data.get("robots", []) or []
    if not isinstance(robots_data, list):
        raise WorldError.at(w("robots"), "must be a list of start poses", robots_data)
    starts = tuple(_parse_start(w(f"robots[{i}]"), r, robot) for i, r in enumerate(robots_data))
    try:
        density = parse_density(data.get("density"), w("density"))
    except WorldError:
        raise
    except ConfigError as exc:
        raise WorldError(str(exc)) from None
    spec = WorldSpec(name=name, source=source, resolution=resolution, bounds=bounds,
                     base_map=base_map, obstacles=obstacles, starts=starts, density=density,
                     robot=robot)
    validate_starts(spec, [(s.x, s.y, s.robot.radius) for s in starts], w("robots"))
    return spec


def validate_starts(spec: WorldSpec, starts: list[tuple[float, float, float]],
                    where: str = "robots") -> None:
    """Raise if a start ``(x, y, radius)`` is off the map, inside an obstacle, or overlaps
    another robot."""
    grid = spec.grid
    for i, (x, y, radius) in enumerate(starts):
        wi = f"{where}[{i}]"
        if not (math.isfinite(x) and math.isfinite(y)):
            raise WorldError.at(wi, "start position must be finite", (x, y))
        if not grid.contains_point(np.array([[x, y]]))[0]:
            xmin, ymin, xmax, ymax = grid.extent()
            raise WorldError.at(wi, "start is outside the map", (x, y),
                                f"x in [{xmin:g}, {xmax:g}], y in [{ymin:g}, {ymax:g}]")
        clearance = spec.start_clearance(x, y)
        if clearance < radius:
            raise WorldError.at(wi, f"start ({x:g}, {y:g}) is inside an obstacle or wall "
                                f"(clearance {clearance:.3f} m < robot radius {radius:g} m)")
        for j in range(i):
            xj, yj, rj = starts[j]
            if math.hypot(x - xj, y - yj) < radius + rj:
                raise WorldError.at(wi, f"start ({x:g}, {y:g}) overlaps robot {j} at "
                                    f"({xj:g}, {yj:g})")


# ---------------------------------------------------------------------------- placement
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
    free = grid.inflated_free_mask(radius + CLUSTER_WALL_MARGIN)
    labels, n = ndimage.label(free, structure=np.ones((3, 3)))
    if n == 0:
        raise WorldError.at("num_robots", "the map has no free space wide enough for a robot "
                            f"of radius {radius:g} m")
    sizes = np.bincount(labels.ravel())[1:]
    region = labels == (int(np.argmax(sizes)) + 1)
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
    from scipy.sparse.csgraph import dijkstra

    from coverage_ros.core.graph import build_grid_graph

    graph = build_grid_graph(free, 1.0, connectivity=8)
    d = dijkstra(graph.csr, indices=int(graph.node_of_cell(np.array(start))))
    return d.reshape(free.shape)
