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
from coverage_ros.core.strategies import STRATEGIES, strategy_choice
from coverage_ros.core.world import load_planar_world
from coverage_ros.core.world.density import Density, parse_density
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.region import Region, parse_region_text
from coverage_ros.core.world.robot import TB3_RADIUS, RobotSpec
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.core.world.yaml_io import yaml_mapping
from coverage_ros.errors import ConfigError
from coverage_ros.worlds import resolve_world_path

#: Body parameter -> RobotSpec field; a value < 0 means "not set: from the world or default".
SPEC_PARAMETERS = {"robot_radius": "radius", "v_max": "v_max", "w_max": "w_max",
                   "a_max": "a_max", "alpha_max": "alpha_max",
                   "sensor_radius": "sensor_radius", "power_weight": "power_weight"}
_UNSET = "; < 0: from the world's entry for this robot, else TurtleBot3 Burger"

PARAMETERS: dict[str, tuple[Any, str]] = {  # name: (default, description)
    "robot_id": (-1, "this robot's id; -1: from the namespace /<robot_prefix><id>"),
    "strategy": ("geodesic", f"coverage strategy: {', '.join(STRATEGIES)}"),
    "strategy_params": ("", "YAML mapping of strategy parameters, e.g. '{method: paper}'"),
    "world": ("", "world name or YAML: robot spec, importance density (and the map when "
              "map_topic is '')"),
    "map_topic": ("/map", "nav_msgs/OccupancyGrid topic (transient local); '': map of 'world'"),
    "density": ("", "YAML importance density overriding the world's (default uniform)"),
    "robot_radius": (-1.0, f"[m] robot radius (inflates the map; TB3 {TB3_RADIUS}){_UNSET}"),
    "v_max": (-1.0, f"[m/s] maximum linear speed{_UNSET}"),
    "w_max": (-1.0, f"[rad/s] maximum angular speed{_UNSET}"),
    "a_max": (-1.0, f"[m/s^2] linear acceleration limit{_UNSET}"),
    "alpha_max": (-1.0, f"[rad/s^2] angular acceleration limit{_UNSET}"),
    "sensor_radius": (-1.0, f"[m] sensing radius (sensor-based strategies, coverage "
                      f"metrics){_UNSET}"),
    "power_weight": (-1.0, f"[m] power weight R of this robot (power Voronoi cells){_UNSET}"),
    "control_rate": (2.0, "[Hz] coverage updates (cell, goal, state), at most"),
    "update_load": (0.1, "largest fraction of one CPU core spent on coverage updates; "
                    "costly updates are spaced out to keep within it"),
    "search_reuse": (0.2, "[m] robots sharing a process (robot_container): a robot takes its "
                     "cell from a whole-map search another one made since its own last update "
                     "when every robot is within this distance of where that search had it "
                     "(geodesic); 0: each robot searches for itself"),
    "tracking_rate": (10.0, "[Hz] path tracking and cmd_vel"),
    "state_rate": (2.5, "[Hz] coverage_state: the last update's values with the current "
                   "position (neighbours' tessellations and safety filters); at most "
                   "tracking_rate"),
    "comm_range": (0.0, "[m] neighbours farther than this are ignored; 0: no limit"),
    "neighbour_timeout": (2.0, "[s] a neighbour silent this long is ignored"),
    "team_size": (0, "robots in the team, this one included (coverage-team sets it): before "
                  "its first update the robot listens until it has heard the other team_size "
                  "- 1 robots' states (or listen_timeout passed); 0: it listens for one look "
                  "at the ROS graph (1.5 s). Once it has found them all it looks at the graph "
                  "for new ones every 10 s instead of every second"),
    "listen_timeout": (10.0, "[s] wall time a robot with team_size waits at most for its team "
                       "before its first update; then it starts with those it heard, warning"),
    "pose_source": ("ground_truth", "where the robot's pose comes from: 'ground_truth' "
                    "(pose_topic) or 'tf' (map -> base_link from /tf, as AMCL or slam_toolbox "
                    "give it)"),
    "pose_topic": ("ground_truth", "nav_msgs/Odometry with the robot pose in the map frame"),
    "scan_topic": ("scan", "sensor_msgs/LaserScan of the robot's lidar"),
    "use_scan": (True, "use the lidar in the safety filter (always on for sensor strategies)"),
    "use_stamped_cmd_vel": (False, "publish geometry_msgs/TwistStamped instead of Twist"),
    "goal_tolerance": (0.05, "[m] a strategy whose goal moves less than this has converged"),
    "arrival_tolerance": (0.05, "[m] the robot stops this near its goal, and a robot at its "
                          "goal follows a new one this far away (Lloyd-type goals creep a "
                          "few cm per update near the end)"),
    "robot_prefix": ("robot_", "namespace prefix of the team's robots (neighbour discovery)"),
    "connectivity": (8, "grid graph neighbourhood: 8 (Bhattacharya et al. 2014) or 16"),
    "explore": (False, "explore an unknown map: no /map; the belief starts unknown on the "
                "lattice of 'world' (or 'bounds') and grows from the lidar and the "
                "neighbours' observations"),
    "bounds": ("", "exploring without 'world': the area 'xmin,ymin,xmax,ymax' [m]"),
    "resolution": (0.05, "[m] cells of the belief when exploring with 'bounds'"),
    "observation_rate": (2.0, "[Hz] exploring: own new evidence published on observations"),
    "observation_cells": (4000, "exploring: most new cells per observations message"),
    "refresh_cells": (2000, "exploring: cells of all own evidence re-sent per observations "
                      "message (repairs lost messages, lets late joiners catch up)"),
    "belief_rate": (1.0, "[Hz] exploring: the belief published as map (OccupancyGrid)"),
    "map_free": (False, "no map at all (strategies that need none: bvc): the domain is the "
                 "extent of 'world' (or 'bounds') with every cell free; cells, goals and "
                 "safety come from the lidar"),
    "manual": (False, "start driven by a person: cmd_vel follows teleop_topic (through the "
               "safety filter) instead of the strategy; switch with the set_manual service"),
    "teleop_topic": ("teleop/cmd_vel", "geometry_msgs/Twist from a person (e.g. "
                     "teleop_twist_keyboard or coverage-teleop), used while manual"),
    "teleop_timeout": (0.5, "[s] a manual robot stops when its teleop topic is silent this "
                       "long"),
    "drive": (True, "drive the robot: cmd_vel from the strategy; false: no cmd_vel, the goal "
              "goes to an external navigator (Nav2's bt_navigator) on goal_topic"),
    "goal_topic": ("goal_pose", "drive: false: geometry_msgs/PoseStamped goals for the "
                   "navigator (Nav2 listens on goal_pose)"),
    "goal_resend_distance": (0.25, "[m] drive: false: a goal is sent again only when it moved "
                             "farther than this"),
    "region": ("", "region of interest at start 'x,y;x,y;...' [m], polygons separated by '|' "
               "(the importance density is kept inside it; /coverage/region changes it at run "
               "time); '': everywhere"),
    "lockstep": (False, "follow the world's lock-step ticks (world_node lockstep: true) instead "
                 "of timers: each tick uses exactly the pose, scans and neighbours' states of "
                 "that tick, updates every control_rate and tracks every tick of sim time, and "
                 "the world waits for the robot's answer"),
}


@dataclass(frozen=True)
class RobotNodeConfig:
    controller: ControllerConfig
    world: str = ""
    map_topic: str = "/map"
    control_rate: float = 2.0
    update_load: float = 0.1
    tracking_rate: float = 10.0
    state_rate: float = 2.5
    pose_topic: str = "ground_truth"
    pose_source: str = "ground_truth"  # or "tf"
    scan_topic: str = "scan"
    use_scan: bool = True
    use_stamped_cmd_vel: bool = False
    robot_prefix: str = "robot_"
    team_size: int = 0  # 0: unknown (listen for LISTEN_FIRST only)
    listen_timeout: float = 10.0  # [s] wall, the longest wait for the team before moving
    connectivity: int = 8
    explore: ExploreIO | None = None  # exploring: the belief's lattice and its traffic
    map_free: GridMap | None = None  # no map: the area, every cell free
    manual: bool = False  # driven by a person from the start
    teleop_topic: str = "teleop/cmd_vel"
    drive: bool = True  # False: goals for an external navigator, no cmd_vel
    goal_topic: str = "goal_pose"
    goal_resend_distance: float = 0.25  # [m]
    lockstep: bool = False  # driven by the world's ticks instead of timers
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

