"""robot_node's parameters and the validated configuration built from them, once, at start-up.

The robot's :class:`~coverage_ros.core.world.robot.RobotSpec` comes from the world file when
the node has one (``world``: its ``robot`` defaults and the ``robots`` entry of this robot's
id), else TurtleBot3 Burger defaults; each body parameter (``robot_radius``, ``v_max``, ...)
that is set (>= 0) overrides its field. ``coverage-team`` passes every field explicitly, so
each robot process runs with exactly the spec its simulated body has.

No rclpy here: the node passes the declared values and its namespace, so the rules can be
tested without ROS.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from coverage_ros.core.control.controller import ControllerConfig
from coverage_ros.core.strategies import strategy_choice
from coverage_ros.core.world import load_planar_world
from coverage_ros.core.world.density import Density, parse_density
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.region import Region, parse_region_text
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.core.world.yaml_io import yaml_mapping
from coverage_ros.errors import ConfigError
from coverage_ros.nodes.robot_parameters import SPEC_PARAMETERS
from coverage_ros.worlds import resolve_world_path


@dataclass(frozen=True)
class RobotNodeConfig:
    """robot_node's configuration: the parameters of the same names (defaults and meanings:
    PARAMETERS), checked, and what they gave at start-up."""

    controller: ControllerConfig
    world: str
    map_topic: str
    control_rate: float  # [Hz]
    update_load: float
    tracking_rate: float  # [Hz]
    state_rate: float  # [Hz]
    pose_topic: str
    pose_source: str  # "ground_truth" or "tf"
    scan_topic: str
    use_scan: bool
    use_stamped_cmd_vel: bool
    robot_prefix: str
    team_size: int  # 0: unknown (listen for LISTEN_FIRST only)
    listen_timeout: float  # [s] wall, the longest wait for the team before moving
    connectivity: int
    manual: bool  # driven by a person from the start
    teleop_topic: str
    drive: bool  # False: goals for an external navigator, no cmd_vel
    goal_topic: str
    goal_resend_distance: float  # [m]
    lockstep: bool  # driven by the world's ticks instead of timers
    explore: ExploreIO | None = None  # exploring: the belief's lattice and its traffic
    map_free: GridMap | None = None  # no map: the area, every cell free
    region: Region = field(default_factory=Region)  # of interest at start (empty: everywhere)

    def __post_init__(self) -> None:
        for name in ("control_rate", "tracking_rate", "state_rate"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError.at(name, "must be a number > 0 [Hz]", v)
        if not (math.isfinite(self.update_load) and 0 < self.update_load <= 1):
            raise ConfigError.at("update_load", "must be a fraction in (0, 1]",
                                 self.update_load)
        if not self.map_topic and not self.world and self.explore is None and \
                self.map_free is None:
            raise ConfigError.at("map_topic", "is empty and no 'world' gives the map", "")
        if self.manual and not self.teleop_topic:
            raise ConfigError.at("teleop_topic", "is empty but the robot starts manual", "")
        if not self.drive:
            if self.manual:
                raise ConfigError.at("drive", "is false but the robot starts manual (a person "
                                     "drives it through this node's cmd_vel)", False)
            if not self.goal_topic:
                raise ConfigError.at("goal_topic", "is empty but drive is false", "",
                                     "the navigator's goal topic, e.g. goal_pose")
        if self.pose_source not in ("ground_truth", "tf"):
            raise ConfigError.at("pose_source", "unknown pose source", self.pose_source,
                                 "'ground_truth' or 'tf'")
        if not (math.isfinite(self.goal_resend_distance) and self.goal_resend_distance >= 0):
            raise ConfigError.at("goal_resend_distance", "must be a number >= 0 [m]",
                                 self.goal_resend_distance)
        if not self.region.everywhere and self.explore is not None:
            raise ConfigError.at("region", "does not apply while exploring (the density is the "
                                 "belief's entropy)", self.region.describe())
        if self.connectivity not in (8, 16):
            raise ConfigError.at("connectivity", "must be 8 or 16", self.connectivity)
        if self.team_size < 0:
            raise ConfigError.at("team_size", "must be an integer >= 0 (0: unknown)",
                                 self.team_size)
        if not (math.isfinite(self.listen_timeout) and self.listen_timeout >= 0):
            raise ConfigError.at("listen_timeout", "must be a number >= 0 [s]",
                                 self.listen_timeout)


@dataclass(frozen=True)
class ExploreIO:
    """An exploring robot's belief lattice and the rates of its evidence traffic."""

    lattice: GridMap  # the area explored, every cell unknown
    observation_rate: float = 2.0  # [Hz]
    observation_cells: int = 4000
    refresh_cells: int = 2000
    belief_rate: float = 1.0  # [Hz]

    def __post_init__(self) -> None:
        for name in ("observation_rate", "belief_rate"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError.at(name, "must be a number > 0 [Hz]", v)
        for name in ("observation_cells", "refresh_cells"):
            if getattr(self, name) < 1:
                raise ConfigError.at(name, "must be >= 1", getattr(self, name))


def explore_lattice(world: WorldSpec | None, bounds: str, resolution: float,
                    what: str = "explore") -> GridMap:
    """The lattice an exploring (or map-free) robot works on: the world's (its extent and
    cells, not its content), else the area ``bounds`` at ``resolution``; every cell
    unknown."""
    if world is not None:
        grid = world.grid
        return GridMap(np.full(grid.shape, -1, np.int8), grid.resolution, grid.origin)
    if not bounds:
        raise ConfigError.at(what, "needs the area: 'world' or 'bounds'", "",
                             "-p world:=office or -p bounds:=xmin,ymin,xmax,ymax")
    try:
        x0, y0, x1, y1 = (float(v) for v in bounds.split(","))
    except ValueError:
        raise ConfigError.at("bounds", "must be four numbers 'xmin,ymin,xmax,ymax'",
                             bounds) from None
    if not (math.isfinite(resolution) and resolution > 0):
        raise ConfigError.at("resolution", "must be a number > 0 [m]", resolution)
    if not (x0 < x1 and y0 < y1) or not all(math.isfinite(v) for v in (x0, y0, x1, y1)):
        raise ConfigError.at("bounds", "need finite xmin < xmax and ymin < ymax", bounds)
    shape = (int(math.ceil((y1 - y0) / resolution)), int(math.ceil((x1 - x0) / resolution)))
    if shape[0] * shape[1] > 25_000_000:
        raise ConfigError.at("bounds", "area too large for the resolution (> 25M cells)",
                             bounds)
    return GridMap(np.full(shape, -1, np.int8), resolution, (x0, y0, 0.0))


@dataclass(frozen=True)
class RobotInputs:
    """What the node loads at start-up besides its parameters."""

    config: RobotNodeConfig
    world: WorldSpec | None  # the world file's description, if 'world' is set
    density: Density | None  # the importance density (parameter 'density', else the world's)


def robot_id_from_namespace(namespace: str, prefix: str) -> int:
    m = re.fullmatch(rf"/{re.escape(prefix)}(\d+)", namespace)
    if not m:
        raise ConfigError.at("robot_id", f"not set and the namespace {namespace!r} is not "
                             f"/{prefix}<id>", -1, f"-p robot_id:=N or -r __ns:=/{prefix}N")
    return int(m.group(1))


def robot_spec(base: RobotSpec, values: dict[str, Any]) -> RobotSpec:
    """``base`` with every body parameter of ``values`` that is set (>= 0) in its place."""
    overrides = {}
    for param, fieldname in SPEC_PARAMETERS.items():
        value = float(values[param])
        if not math.isfinite(value):
            raise ConfigError.at(param, "must be a finite number", value)
        if value >= 0:
            overrides[fieldname] = value
    try:
        return base.with_overrides(overrides, where="parameters")
    except ConfigError as exc:
        raise ConfigError(str(exc).replace("parameters: robot.", "parameter ")) from None


def load_robot_inputs(values: dict[str, Any], namespace: str,
                      load_world: Callable[[str], WorldSpec] | None = None) -> RobotInputs:
    """Validate the declared parameter ``values`` of a node in ``namespace``; load the world
    file (through ``load_world``, e.g. one shared by the robots of a process) and density
    they name."""
    prefix = values["robot_prefix"]
    rid = values["robot_id"] if values["robot_id"] >= 0 else robot_id_from_namespace(
        namespace, prefix)
    load_world = load_world or (lambda name: load_planar_world(Path(resolve_world_path(name))))
    world = load_world(values["world"]) if values["world"] else None
    base = world.robot_spec(rid) if world is not None else RobotSpec()
    choice = strategy_choice(values["strategy"],
                             yaml_mapping(values["strategy_params"], "strategy_params"),
                             explore=bool(values["explore"]))
    map_free = None
    if values["map_free"]:
        if choice.needs_map:
            raise ConfigError.at("map_free", f"strategy {choice.name} needs a map", True,
                                 "a strategy that works from its lidar alone: bvc")
        if values["explore"]:
            raise ConfigError.at("map_free", "and explore exclude each other", True)
        area = explore_lattice(world, values["bounds"], values["resolution"], "map_free")
        map_free = area.with_occupancy(np.zeros(area.shape, np.int8))
    explore = None
    if values["explore"]:
        explore = ExploreIO(explore_lattice(world, values["bounds"], values["resolution"]),
                            values["observation_rate"], values["observation_cells"],
                            values["refresh_cells"], values["belief_rate"])
    controller = ControllerConfig(
        robot_id=rid, strategy=choice, robot=robot_spec(base, values),
        comm_range=values["comm_range"], neighbour_timeout=values["neighbour_timeout"],
        goal_tolerance=values["goal_tolerance"], arrival_tolerance=values["arrival_tolerance"],
        teleop_timeout=values["teleop_timeout"], search_reuse=values["search_reuse"])
    config = RobotNodeConfig(
        controller=controller, world=values["world"], map_topic=values["map_topic"],
        control_rate=values["control_rate"], update_load=values["update_load"],
        tracking_rate=values["tracking_rate"], state_rate=values["state_rate"],
        pose_topic=values["pose_topic"], pose_source=values["pose_source"],
        scan_topic=values["scan_topic"],
        use_scan=values["use_scan"], use_stamped_cmd_vel=values["use_stamped_cmd_vel"],
        robot_prefix=prefix, team_size=values["team_size"],
        listen_timeout=values["listen_timeout"], connectivity=values["connectivity"],
        explore=explore,
        map_free=map_free,
        manual=bool(values["manual"]), teleop_topic=values["teleop_topic"],
        drive=bool(values["drive"]), goal_topic=values["goal_topic"],
        goal_resend_distance=values["goal_resend_distance"], lockstep=bool(values["lockstep"]),
        region=Region(tuple(parse_region_text(t, "region")
                            for t in values["region"].split("|") if t.strip())))
    density = world.density if world is not None else None
    if values["density"]:
        density = parse_density(yaml_mapping(values["density"], "density"), "density")
    return RobotInputs(config, world, density)

