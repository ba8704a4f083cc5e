"""robot_node's parameters, each declared once (:data:`PARAMETERS`): defaults and meanings,
from which the node declares them and config/robot.yaml and the reference are generated."""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from coverage_ros.core.control.controller import ControllerConfig
from coverage_ros.core.strategies import STRATEGIES
from coverage_ros.core.world.robot import RobotSpec

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
                          "follows a new one this far away. Lloyd-type goals creep a few cm "
                          "per update near the end, so a smaller tolerance lets a team settle "
                          "closer to its centroids (the papers' live experiments use 0.02)"),
    "robot_prefix": ("robot_", "namespace prefix of the team's robots (neighbour discovery)"),
    "connectivity": (8, "grid graph neighbourhood: 8 (Bhattacharya et al. 2014) or 16"),
    "explore": (False, "explore an unknown map (docs: Concepts, Exploration): no "
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
                      "safety filter instead of the strategy (docs: Tutorials, A mixed team and "
                      "a person driving); switch with the `set_manual` service"),
    "teleop_topic": ("teleop/cmd_vel", "`geometry_msgs/Twist` from a person "
                                       "(`teleop_twist_keyboard`, `coverage-teleop`), used while "
                                       "manual"),
    "teleop_timeout": (_CORE["teleop_timeout"],
                       "[s] a manual robot stops when its teleop topic is silent this "
                       "long"),
    "drive": (True, "drive the robot: `cmd_vel` from the strategy; `false`: no `cmd_vel` "
                    "publisher at all, the goal goes to the robot's own navigator on `goal_topic`"
                    " (docs: Tutorials, On your own robots)"),
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
    "lockstep": (False, "follow the world's lock-step ticks (docs: Concepts, Lock-step; "
                        "`world_node` with `lockstep: true`) instead of timers: each tick uses "
                        "exactly the pose, scans and neighbours' states of that tick, the "
                        "coverage update comes every `control_rate` of sim time (first at tick 1,"
                        " once every robot knows every other's start), tracking and "
                        "`coverage_state` every tick; `tracking_rate`, `state_rate`, "
                        "`update_load`, `team_size` and `listen_timeout` do not apply"),
}
