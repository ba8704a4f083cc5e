"""Loading worlds: the package's world YAML, or a plain map_server map (a world of that map).

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
      - {pose: [2.0, 1.0, 0.0], radius: 0.15, v_max: 0.3, sensor_radius: 2.0}
    density: {type: gaussian_mixture, components: [{mean: [8, 6], sigma: 1.0}]}

Everything is validated when loaded; errors name the file and the field.
"""
from __future__ import annotations

import math
from collections.abc import Set
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from coverage_ros.core.geometry import box_polygon, polygon_area, segment_polygon
from coverage_ros.core.world.density import parse_density
from coverage_ros.core.world.map_server import grid_from_map_yaml, is_map_server_yaml
from coverage_ros.core.world.metric import CHART_KEYS, ChartSpec, MetricRegion, WorldMetric
from coverage_ros.core.world.obstacles import Obstacle
from coverage_ros.core.world.placement import validate_starts
from coverage_ros.core.world.robot import LIDAR_KEYS, ROBOT_KEYS, LidarSpec, RobotSpec
from coverage_ros.core.world.spec import DEFAULT_RESOLUTION, StartPose, WorldSpec
from coverage_ros.core.world.yaml_io import read_yaml_mapping
from coverage_ros.errors import ConfigError, WorldError


def _where(source: str, fieldname: str) -> str:
    return f"{source}: {fieldname}" if source else fieldname


_WORLD_KEYS = {"name", "description", "resolution", "bounds", "map", "obstacles", "robots",
               "robot", "lidar", "density", "metric", "chart"}
_OBSTACLE_KEYS = {
    "box": {"type", "center", "size", "yaw"},
    "polygon": {"type", "points"},
    "circle": {"type", "center", "radius"},
    "wall": {"type", "from", "to", "thickness"},
}


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


def _check_keys(where: str, data: dict[str, Any], allowed: Set[str]) -> None:
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise WorldError.at(_join(where, unknown[0]), "unknown key",
                            expected=f"one of {sorted(allowed)}")


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where and not where.endswith(": ") else f"{where}{key}"


def _parse_lidar(where: str, data: Any, base: LidarSpec) -> LidarSpec:
    if not isinstance(data, dict):
        raise WorldError.at(where, "must be a mapping of lidar settings", data)
    _check_keys(where, data, LIDAR_KEYS)
    values: dict[str, Any] = {}
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


#: ``power_weight: sensor`` - the power weight is the robot's sensor radius.
POWER_FROM_SENSOR = "sensor"


def parse_robot_entry(where: str, data: Any, base: RobotSpec) -> RobotSpec:
    """A robot mapping (RobotSpec fields; ``lidar`` a mapping of LidarSpec fields;
    ``power_weight`` a number [m] or ``sensor``) over ``base``: the spec it describes."""
    if not isinstance(data, dict):
        raise WorldError.at(where, "must be a mapping of robot settings", data)
    _check_keys(where, data, ROBOT_KEYS)
    values: dict[str, Any] = {}
    for key, value in data.items():
        if key == "power_weight" and value == POWER_FROM_SENSOR:
            continue  # resolved below, from the sensor radius this entry ends up with
        if key == "power_weight" and isinstance(value, str):
            raise WorldError.at(_join(where, key), "unknown power weight", value,
                                f"a number >= 0 [m] or '{POWER_FROM_SENSOR}'")
        if key == "lidar":
            values[key] = _parse_lidar(_join(where, key), value, base.lidar)
        else:
            values[key] = _num(_join(where, key), value, positive=key != "power_weight")
            if values[key] < 0:
                raise WorldError.at(_join(where, key), "must be >= 0 [m]", value)
    if data.get("power_weight") == POWER_FROM_SENSOR:
        # Bhattacharya et al. (Fig. 19): the power weight is the sensor footprint's radius.
        values["power_weight"] = values.get("sensor_radius", base.sensor_radius)
    try:
        return replace(base, **values)
    except ConfigError as exc:
        raise WorldError(f"{where}: {exc}") from None


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
        if abs(polygon_area(poly)) < 1e-12:
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


def _parse_chart(where: str, data: Any) -> ChartSpec:
    if not isinstance(data, dict) or data.get("type") not in CHART_KEYS:
        raise WorldError.at(where, "must be a mapping with a 'type'", data,
                            f"type one of {sorted(CHART_KEYS)}")
    kind = data["type"]
    _check_keys(where, data, set(CHART_KEYS[kind]))
    values = {k: v for k, v in CHART_KEYS[kind].items() if k != "type"} | {
        k: v for k, v in data.items() if k != "type"}
    count = values.pop("cells_per_pi" if kind == "sphere" else "cells")
    if isinstance(count, bool) or not isinstance(count, int) or not 8 <= count <= 1024:
        raise WorldError.at(_join(where, "cells_per_pi" if kind == "sphere" else "cells"),
                            "must be an integer in 8..1024", count)
    nums = {k: _num(_join(where, k), v, positive=True) for k, v in values.items()}
    if kind == "sphere" and not nums["cap"] < 90.0:
        raise WorldError.at(_join(where, "cap"), "must be < 90 [deg]", nums["cap"])
    if kind == "torus" and not nums["R"] > nums["r"]:
        raise WorldError.at(_join(where, "R"), "must exceed r (a ring torus)", nums["R"])
    return ChartSpec(kind, count, **nums)


def _parse_metric(where: str, data: Any) -> WorldMetric:
    if not isinstance(data, dict):
        raise WorldError.at(where, "must be a mapping with 'zeta' and/or 'regions'", data)
    _check_keys(where, data, {"zeta", "regions"})
    zeta = _num(_join(where, "zeta"), data.get("zeta", 1.0), positive=True)
    regions_data = data.get("regions", []) or []
    if not isinstance(regions_data, list):
        raise WorldError.at(_join(where, "regions"), "must be a list of shapes with a zeta",
                            regions_data)
    regions = []
    for k, entry in enumerate(regions_data):
        wk = _join(where, f"regions[{k}]")
        if not isinstance(entry, dict) or "zeta" not in entry:
            raise WorldError.at(wk, "must be a shape mapping with a 'zeta'", entry,
                                "e.g. {type: box, center: [x, y], size: [w, h], zeta: 4.0}")
        shape = _parse_obstacle(wk, {key: v for key, v in entry.items() if key != "zeta"})
        regions.append(MetricRegion(shape, _num(_join(wk, "zeta"), entry["zeta"],
                                                positive=True)))
    return WorldMetric(zeta, tuple(regions))


def _parse_start(where: str, data: Any, base: RobotSpec) -> StartPose:
    if isinstance(data, list | tuple):
        pose, spec = data, base
    elif isinstance(data, dict):
        if "pose" not in data:
            raise WorldError.at(where, "robot entry needs a 'pose: [x, y, yaw]'", data)
        rest = {k: v for k, v in data.items() if k != "pose"}
        pose = data["pose"]
        spec = parse_robot_entry(where, rest, base) if rest else base
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


def load_planar_world(path: str | Path, where: str = "world") -> WorldSpec:
    """:func:`load_world` for what simulates or drives robots: a chart world (a sphere or a
    torus) is refused - only ``coverage-plan`` runs on a curved surface."""
    world = load_world(path)
    if world.chart is not None:
        raise WorldError.at(where, f"is a {world.chart.kind} chart: robots can only be planned "
                            "on it offline (coverage-plan), not simulated or driven", str(path))
    return world


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
    chart = None
    if "chart" in data:
        clash = sorted({"map", "bounds", "obstacles", "metric"} & set(data))
        if clash:
            raise WorldError.at(w(clash[0]), "does not go with 'chart' (a chart is the whole "
                                "world: its coordinates, metric and blocked parts)")
        chart = _parse_chart(w("chart"), data["chart"])
        base_map = chart.lattice()
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
        raise WorldError.at(w("bounds"), "required when no 'map' or 'chart' is given",
                            expected="[xmin, ymin, xmax, ymax]")
    robot = RobotSpec()
    if "robot" in data:
        robot = parse_robot_entry(w("robot"), data["robot"], robot)
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
    metric = _parse_metric(w("metric"), data["metric"]) if "metric" in data else None
    try:
        density = parse_density(data.get("density"), w("density"))
    except WorldError:
        raise
    except ConfigError as exc:
        raise WorldError(str(exc)) from None
    spec = WorldSpec(name=name, source=source, resolution=resolution, bounds=bounds,
                     base_map=base_map, obstacles=obstacles, starts=starts, density=density,
                     robot=robot, metric=metric, chart=chart)
    validate_starts(spec, [(s.x, s.y, s.yaw) for s in starts], [s.robot.radius for s in starts],
                    w("robots"))
    return spec
