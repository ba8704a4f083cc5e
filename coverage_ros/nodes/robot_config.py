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
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from coverage_ros.core.control.controller import ControllerConfig
from coverage_ros.core.strategies import STRATEGIES, strategy_choice
from coverage_ros.core.world import load_planar_world
from coverage_ros.core.world.density import Density, parse_density
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.region import Region, parse_region_text
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.core.world.yaml_io import yaml_mapping
from coverage_ros.errors import ConfigError
from coverage_ros.worlds import resolve_world_path

#: Body parameter -> RobotSpec field; a value < 0 means "not set: from the world or default".
SPEC_PARAMETERS = {"robot_radius": "radius", "v_max": "v_max", "w_max": "w_max",
                   "a_max": "a_max", "alpha_max": "alpha_max",
                   "sensor_radius": "sensor_radius", "power_weight": "power_weight"}
_BURGER = RobotSpec()
#: The controller's defaults (core): the parameters that configure it start from them.
_CORE = {f.name: f.default for f in fields(ControllerConfig)}


def _unset(field: str) -> str:
    return f"; < 0: from the world's entry for this robot, else TurtleBot3 Burger's " \
        f"{getattr(_BURGER, field):g}"


PARAMETERS: dict[str, tuple[Any, str]] = {  # name: (default, description)
    "robot_id": (-1, "this robot's id; -1: from the namespace /<robot_prefix><id>"),
    "strategy": ("geodesic", f"coverage strategy: {', '.join(STRATEGIES)}"),
    "strategy_params": ("", "YAML mapping of strategy parameters, e.g. '{method: paper}'"),
    "world": ("", "world name or YAML: robot spec, importance density (and the map when "
              "map_topic is '')"),
    "map_topic": ("/map", "nav_msgs/OccupancyGrid topic (transient local); '': map of 'world'"),
    "density": ("", "YAML importance density overriding the world's (default uniform)"),
    "robot_radius": (-1.0, "[m] robot radius (inflates the map)" + _unset("radius")),
    "v_max": (-1.0, "[m/s] maximum linear speed" + _unset("v_max")),
    "w_max": (-1.0, "[rad/s] maximum angular speed" + _unset("w_max")),
    "a_max": (-1.0, "[m/s^2] linear acceleration limit" + _unset("a_max")),
    "alpha_max": (-1.0, "[rad/s^2] angular acceleration limit" + _unset("alpha_max")),
    "sensor_radius": (-1.0, "[m] sensing radius (sensor-based strategies, coverage metrics)"
                      + _unset("sensor_radius")),
    "power_weight": (-1.0, "[m] power weight R of this robot (power Voronoi cells)"
                     + _unset("power_weight")),
    "control_rate": (2.0, "[Hz] coverage updates (cell, goal, state), at most"),
    "update_load": (0.1, "largest fraction of one CPU core spent on coverage updates, on average:"
                         " a CPU-time credit grows by `update_load` per second (up to 1 s) and "
                         "each update spends its CPU time; none starts while the credit is "
                         "negative (updates run on their own thread; tracking never waits for "
                         "them). An update asked for while the credit is negative waits for it "
                         "and then runs at the node's time of its start. In a `robot_container` "
                         "the robots pool their credits (growing by the sum of their loads, up to"
                         " one robot's burst) and queue for the process's one update slot and the"
                         " credit, the robot whose last update started longest ago first: a robot"
                         " with a large cell uses what robots with small cells leave, and none of"
                         " them jumps the queue"),
    "search_reuse": (_CORE["search_reuse"],
                     "[m] robots sharing a process (`robot_container`) share whole-map "
                     "searches: a robot takes its cell from the process's last whole-map "
                     "search when another robot made it since this robot's own last update "
                     "and every robot is within this distance of where that search had it, "
                     "one to one (the exact cell of so near a team; `geodesic` only, equal "
                     "power weights). A robot never steers twice by the same approximate "
                     "search, and a robot alone in its process never by one; 0: each robot "
                     "searches for itself (`coverage-team` sets 0.2 for robots sharing a "
                     "process)"),
    "tracking_rate": (10.0, "[Hz] path tracking and cmd_vel"),
    "state_rate": (2.5, "[Hz] `coverage_state`: the last update's values with the current "
                        "position (what the neighbours' tessellations and safety filters use); at"
                        " most `tracking_rate`"),
    "comm_range": (_CORE["comm_range"],
                   "[m] neighbours farther than this are ignored; 0: no limit"),
    "neighbour_timeout": (_CORE["neighbour_timeout"],
                          "[s] a neighbour silent this long is ignored"),
    "team_size": (0, "robots in the team, this one included (`coverage-team` sets it): before its"
                     " first update the robot listens until it has heard the other `team_size - "
                     "1` robots' states (or `listen_timeout` passed); 0: it listens for one look "
                     "at the ROS graph (1.5 s). Once it has found them all, it looks at the ROS "
                     "graph for new ones every 10 s instead of every second (a look at a graph of"
                     " 32 robot processes costs ~9 ms)"),
    "listen_timeout": (10.0, "[s] wall time a robot with `team_size` waits at most for its team "
                             "before its first update; then it starts with those it heard, with a"
                             " warning"),
    "pose_source": ("ground_truth", "where the pose comes from: `ground_truth` (the Odometry on "
                                    "`pose_topic`) or `tf` (`map -> base_link` from /tf, as AMCL "
                                    "or slam_toolbox give it)"),
    "pose_topic": ("ground_truth", "nav_msgs/Odometry with the robot pose in the map frame"),
    "scan_topic": ("scan", "sensor_msgs/LaserScan of the robot's lidar"),
    "use_scan": (True, "use the lidar in the safety filter (always on for sensor strategies)"),
    "use_stamped_cmd_vel": (False, "publish geometry_msgs/TwistStamped instead of Twist"),
    "goal_tolerance": (_CORE["goal_tolerance"],
                       "[m] a strategy whose goal moves less than this has converged"),
    "arrival_tolerance": (_CORE["arrival_tolerance"],
                          "[m] the robot stops this near its goal, and a robot at its goal "
                          "follows a new one this far away. Lloyd-type goals creep a few cm"
                          " per update near the end: robots that kept still for goals "
                          "within 5 cm ended Lee & Lee's Fig. 17a-c at I 0.06-0.07 in three"
                          " starts of five, with 0.02 at 0.034-0.038 in four (the paper "
                          "bench sets 0.02); 0.02 is not the default yet: with it, an "
                          "exploring robot touched a wall once in the tb3_sandbox "
                          "exploration test (untraced)"),
    "robot_prefix": ("robot_", "namespace prefix of the team's robots (neighbour discovery)"),
    "connectivity": (8, "grid graph neighbourhood: 8 (Bhattacharya et al. 2014) or 16"),
    "explore": (False, "explore an unknown map (README \"Exploring an unknown building\"): no "
                       "`/map`; the belief starts unknown on the lattice of `world` (its extent "
                       "and cells, not its content) or of `bounds`, and grows from the lidar and "
                       "the neighbours' `observations`; `strategy` is then `geodesic` or "
                       "`frontier`"),
    "bounds": ("", "exploring without `world`: the area `xmin,ymin,xmax,ymax` [m]"),
    "resolution": (0.05, "[m] cells of the belief when exploring with `bounds`"),
    "observation_rate": (2.0, "[Hz] exploring: own new evidence published on `observations`"),
    "observation_cells": (4000, "exploring: most new cells per `observations` message"),
    "refresh_cells": (2000, "exploring: cells of all the own evidence re-sent in each "
                            "`observations` message, round robin (repairs lost messages; late "
                            "joiners catch up)"),
    "belief_rate": (1.0, "[Hz] exploring: the belief published as `map`"),
    "map_free": (False, "no map at all, for strategies that need none (`bvc`): the domain is the "
                        "extent of `world` (or `bounds` at `resolution`) with every cell free, no"
                        " `/map` subscription; cells, goals and safety come from the lidar (Wang "
                        "et al.)"),
    "manual": (False, "start driven by a person: `cmd_vel` follows `teleop_topic` through the "
                      "safety filter instead of the strategy (README \"Driving a robot "
                      "yourself\"); switch with the `set_manual` service"),
    "teleop_topic": ("teleop/cmd_vel", "`geometry_msgs/Twist` from a person "
                                       "(`teleop_twist_keyboard`, `coverage-teleop`), used while "
                                       "manual"),
    "teleop_timeout": (_CORE["teleop_timeout"],
                       "[s] a manual robot stops when its teleop topic is silent this "
                       "long"),
    "drive": (True, "drive the robot: `cmd_vel` from the strategy; `false`: no `cmd_vel` "
                    "publisher at all, the goal goes to the robot's own navigator on `goal_topic`"
                    " (README \"Using it on your robots\")"),
    "goal_topic": ("goal_pose", "`drive: false`: `geometry_msgs/PoseStamped` goals for the "
                                "navigator (Nav2's bt_navigator listens on `goal_pose`)"),
    "goal_resend_distance": (0.25, "[m] `drive: false`: a goal is sent again only when it moved "
                                   "farther than this from the last one sent (a navigator replans"
                                   " on every goal); the last one sent is repeated when a "
                                   "subscriber appeared on `goal_topic` since"),
    "region": ("", "region of interest at start, `x,y;x,y;...` [m] with polygons separated by "
                   "`|`: the importance density is kept inside it from the first update on "
                   "(`coverage-team --region` sets it; `/coverage/region` changes it at run time,"
                   " and a polygon already held changes nothing); `''`: everywhere"),
    "lockstep": (False, "follow the world's lock-step ticks (README \"Lock-step simulation\"; "
                        "`world_node` with `lockstep: true`) instead of timers: each tick uses "
                        "exactly the pose, scans and neighbours' states of that tick, the "
                        "coverage update comes every `control_rate` of sim time (first at tick 1,"
                        " once every robot knows every other's start), tracking and "
                        "`coverage_state` every tick; `tracking_rate`, `state_rate`, "
                        "`update_load`, `team_size` and `listen_timeout` do not apply"),
}


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

