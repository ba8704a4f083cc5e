"""coverage-team's command line: the options, and the checks of their values that need no
world (``--kill``/``--restart`` schedules)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from coverage_ros.core.strategies import EXPLORERS, STRATEGIES
from coverage_ros.errors import ConfigError
from coverage_ros.nodes.runner import EXECUTORS


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="coverage-team",
                                 description="run a coverage team - the world node and one "
                                 "robot process per robot")
    ap.add_argument("--robots", type=int, default=None,
                    help="team size (default 4, or the team file's)")
    ap.add_argument("--team", type=Path, metavar="TEAM.yaml",
                    help="the robots: id, start, spec fields and role of each (see "
                    "config/teams/); values not given come from the world")
    ap.add_argument("--human", type=int, action="append", default=[], metavar="ID",
                    help="robot ID is driven by a person (its teleop topic) from the start; "
                    "repeatable")
    ap.add_argument("--world", default="office",
                    help="package world YAML, map_server YAML or a shipped world name")
    ap.add_argument("--strategy", default="geodesic",
                    choices=sorted(set(STRATEGIES) | set(EXPLORERS)),
                    help="coverage strategy; exploring: geodesic or frontier")
    ap.add_argument("--strategy-params", default="",
                    help="YAML mapping of strategy settings for every robot, e.g. "
                    "'{variant: nearest}' (robot_node's strategy_params)")
    ap.add_argument("--explore", action="store_true",
                    help="the robots start with no map and explore (the world's true map is "
                    "only simulated and used for scoring)")
    ap.add_argument("--map-free", action="store_true",
                    help="the robots get no map (strategies that need none: bvc); the world "
                    "node still simulates the world's")
    ap.add_argument("--until-explored", type=float, default=None, metavar="F",
                    help="with --explore: end the run once the team has explored this share "
                    "of the reachable free area")
    ap.add_argument("--duration", type=float, default=60.0, help="[s] simulated time to run")
    ap.add_argument("--seed", type=int, default=0, help="start cluster and simulator seed")
    ap.add_argument("--starts", help="start poses 'x,y,yaw;...' (default: the world's start "
                    "poses if it lists one per robot, else a compact seeded cluster, so the "
                    "robots must spread)")
    ap.add_argument("--lockstep", action="store_true",
                    help="lock-step simulation: the world advances a tick only when every "
                    "robot has answered the last, so the same command and seed give the same "
                    "summary, as fast as the robots' work allows (README \"Lock-step "
                    "simulation\")")
    ap.add_argument("--rtf", type=float, default=None,
                    help="real-time factor of the simulation (0: as fast as possible; default "
                    "1, with --lockstep none: --rtf caps its pace)")
    ap.add_argument("--out", type=Path, help="output folder (default out/team-<time>)")
    ap.add_argument("--record", action="store_true", help="write <out>/recording.rrd")
    ap.add_argument("--viewer", action="store_true", help="stream to a spawned rerun viewer")
    ap.add_argument("--serve-web", action="store_true",
                    help="serve the rerun web viewer on 127.0.0.1")
    ap.add_argument("--domain-id", type=int, help="ROS_DOMAIN_ID (default: a fresh one)")
    ap.add_argument("--control-rate", type=float, default=2.0, help="[Hz] coverage updates")
    ap.add_argument("--update-load", type=float, default=None,
                    help="robot_node update_load: CPU share of one core each robot may spend "
                    "on coverage updates (default: the team's fair share of 15 %% of the "
                    "machine's cores, 50 %% with several robots per process, at most 0.1)")
    ap.add_argument("--state-rate", type=float, default=None,
                    help="[Hz] robot_node state_rate (default: 2.5, lower for robots that run "
                    "alone in a big team: each then handles at most 40 states a second)")
    ap.add_argument("--clock-rate", type=float, default=10.0,
                    help="[Hz, sim time] /clock rate; every message wakes every robot process "
                    "(0: every physics step)")
    ap.add_argument("--odom-rate", type=float, default=10.0,
                    help="[Hz, sim time] odom and ground_truth rate (Stage's 10 Hz)")
    ap.add_argument("--sensor-radius", type=float, default=None,
                    help="[m] every robot's sensing radius (coverage_ratio, sensor-based "
                    "strategies); default: each robot's from the world (TurtleBot3: 3.5)")
    ap.add_argument("--robot-param", action="append", default=[], metavar="NAME:=VALUE",
                    help="extra robot_node parameter (repeatable), e.g. strategy_params:={...}")
    ap.add_argument("--robots-per-process", type=int, default=None, metavar="K",
                    help="robots sharing one process (robot_container; default: 1 up to "
                    "8 robots per core, beyond that as many as make 2 processes per core)")
    ap.add_argument("--kill", action="append", default=[], metavar="ID@SECONDS",
                    help="kill robot ID's process at that sim time (robot loss experiments)")
    ap.add_argument("--region", action="append", default=[], metavar="x,y;x,y;...",
                    help="region of interest [m] (repeatable: a union of polygons): the "
                         "importance density is kept inside it; changeable at run time on "
                         "/coverage/region")
    ap.add_argument("--no-markers", action="store_true",
                    help="do not start marker_node (RViz markers on /coverage/markers)")
    ap.add_argument("--restart", action="append", default=[], metavar="ID@SECONDS",
                    help="kill robot ID's process at that sim time and start it again at once "
                         "(its body stays): a crashed node that comes back")
    ap.add_argument("--stats", action="store_true",
                    help="sample CPU and memory of every process into summary.json")
    ap.add_argument("--remote-robots", metavar="ID,ID,...",
                    help="robots whose processes run on other hosts: the world simulates them, "
                    "the launcher prints (and writes to <out>/remote/) the command for each "
                    "host and waits for them to join")
    ap.add_argument("--discovery-server", nargs="?", const="127.0.0.1", metavar="IPV4[:PORT]",
                    help="run a Fast DDS discovery server on this address (default "
                    "127.0.0.1:11811) and make every process a client of it "
                    "(ROS_DISCOVERY_SERVER) instead of simple discovery")
    ap.add_argument("--executor", choices=EXECUTORS, default=None,
                    help="rclpy executor of every node process (COVERAGE_ROS_EXECUTOR; default "
                    "events: rclpy's EventsExecutor, a fraction of the CPU per message; "
                    "single: SingleThreadedExecutor)")
    ap.add_argument("--quiet", action="store_true", help="no progress display")
    return ap


def parse_faults(kills: list[str], restarts: list[str], n: int) -> list[tuple[float, int, str]]:
    """``--kill`` and ``--restart`` ``ID@SECONDS`` items, sorted by time."""
    out = []
    for option, action, specs in (("--kill", "kill", kills), ("--restart", "restart", restarts)):
        for spec in specs:
            try:
                rid, t = spec.split("@")
                out.append((float(t), int(rid), action))
            except ValueError:
                raise ConfigError.at(option, "must be ID@SECONDS", spec) from None
            if not 0 <= out[-1][1] < n:
                raise ConfigError.at(option, f"robot id out of range 0..{n - 1}", spec)
            if not (math.isfinite(out[-1][0]) and out[-1][0] >= 0):
                raise ConfigError.at(option, "needs a time >= 0 [s]", spec)
    killed = {rid: t for t, rid, action in out if action == "kill"}
    for t, rid, action in out:
        if action == "restart" and killed.get(rid, math.inf) <= t:
            raise ConfigError.at("--restart", f"robot {rid} is killed (--kill) before that",
                                 f"{rid}@{t:g}")
    return sorted(out)
