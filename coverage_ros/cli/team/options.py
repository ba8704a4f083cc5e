"""coverage-team's command line: the options, read into a frozen :class:`RunConfig` whose
values are checked here as far as they can be without the world (nothing below this module
sees the argparse ``Namespace``)."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

from coverage_ros.cli.arguments import attach_values
from coverage_ros.cli.team.network import parse_discovery_address
from coverage_ros.cli.team.robots import robot_params
from coverage_ros.core.strategies import EXPLORERS, STRATEGIES, StrategyChoice, strategy_choice
from coverage_ros.core.world.region import Region, parse_region_text
from coverage_ros.core.world.yaml_io import yaml_mapping
from coverage_ros.errors import ConfigError
from coverage_ros.nodes.robot_parameters import PARAMETERS
from coverage_ros.nodes.runner import EXECUTORS, executor_kind


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
                    "'{escape: false}' (robot_node's strategy_params)")
    ap.add_argument("--explore", action="store_true",
                    help="the robots start with no map and explore (the world's true map is "
                    "only simulated and used for scoring)")
    ap.add_argument("--map-free", action="store_true",
                    help="the robots get no map (strategies that need none: bvc); the world "
                    "node still simulates the world's")
    ap.add_argument("--until-explored", type=float, default=None, metavar="F",
                    help="with --explore: end the run once the team has explored this share "
                    "of the reachable free area")
    ap.add_argument("--until-settled", type=float, default=None, metavar="S",
                    help="[s] end the run before --duration once the team has settled: H "
                    "within 1 %% and no robot moving between cells for S seconds of sim time")
    ap.add_argument("--duration", type=float, default=60.0, help="[s] simulated time to run")
    ap.add_argument("--seed", type=int, default=0, help="start cluster and simulator seed")
    ap.add_argument("--starts", help="start poses 'x,y,yaw;...' (default: the world's start "
                    "poses if it lists one per robot, else a compact seeded cluster, so the "
                    "robots must spread)")
    ap.add_argument("--lockstep", action="store_true",
                    help="lock-step simulation: the world advances a tick only when every "
                    "robot has answered the last, so the same command and seed give the same "
                    "summary, as fast as the robots' work allows (docs: Concepts, "
                    "Lock-step)")
    ap.add_argument("--rtf", type=float, default=None,
                    help="real-time factor of the simulation (0: as fast as possible; default "
                    "1, with --lockstep none: --rtf caps its pace)")
    ap.add_argument("--out", type=Path, help="output folder (default out/team-<time>)")
    ap.add_argument("--record", action="store_true", help="write <out>/recording.rrd")
    ap.add_argument("--viewer", action="store_true", help="stream to a spawned rerun viewer")
    ap.add_argument("--serve-web", action="store_true",
                    help="serve the rerun web viewer on 127.0.0.1")
    ap.add_argument("--domain-id", type=int, help="ROS_DOMAIN_ID (default: a fresh one)")
    ap.add_argument("--control-rate", type=float, default=PARAMETERS["control_rate"][0],
                    help="[Hz] coverage updates (robot_node control_rate)")
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
    ap.add_argument("--no-fork-server", action="store_true",
                    help="start every robot process as a new interpreter, as ros2 run does "
                    "(default: forked from one that has loaded their code, which saves about "
                    "1.2 s of CPU per robot process)")
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
    ap.add_argument("--quiet", action="store_true",
                    help="print nothing but errors (no progress, no summary lines)")
    return ap




@dataclass(frozen=True)
class RunConfig:
    """One ``coverage-team`` run as asked for, every value checked that can be without the world
    (the team size, starts and room are checked by :mod:`.plan`). Field meanings: the options
    of :func:`build_parser` of the same name."""

    world: str = "office"
    strategy: str = "geodesic"
    strategy_params: str = ""
    choice: StrategyChoice | None = None  # the strategy and its settings, checked
    robots: int | None = None
    team_file: Path | None = None
    humans: tuple[int, ...] = ()
    explore: bool = False
    map_free: bool = False
    until_explored: float | None = None
    until_settled: float | None = None  # [s] sim time
    duration: float = 60.0  # [s] sim time
    seed: int = 0
    starts: str | None = None
    lockstep: bool = False
    rtf: float = 1.0  # real-time factor; 0: as fast as possible
    out: Path | None = None
    record: bool = False
    viewer: bool = False
    serve_web: bool = False
    domain_id: int | None = None
    control_rate: float = PARAMETERS["control_rate"][0]  # [Hz]
    update_load: float | None = None
    state_rate: float | None = None  # [Hz]
    clock_rate: float = 10.0  # [Hz, sim time]
    odom_rate: float = 10.0  # [Hz, sim time]
    sensor_radius: float | None = None  # [m]
    robot_params: Mapping[str, object] = field(default_factory=lambda: MappingProxyType({}))
    robots_per_process: int | None = None
    fork_server: bool = True  # robot processes forked from a preloaded interpreter
    kills: tuple[str, ...] = ()
    restarts: tuple[str, ...] = ()
    regions: tuple[str, ...] = ()  # region of interest polygons as given, "x,y;x,y;..."
    region: Region = field(default_factory=Region)
    markers: bool = True
    stats: bool = False
    remote_robots: str | None = None
    discovery: tuple[str, int] | None = None  # the discovery server's (address, port)
    executor: str = "events"
    quiet: bool = False

    @property
    def visualized(self) -> bool:
        """The rerun bridge runs (recording, a viewer or the web viewer)."""
        return self.record or self.viewer or self.serve_web


def parse_config(argv: list[str] | None = None) -> RunConfig:
    """The run configuration of a command line (``sys.argv[1:]`` by default); argparse exits
    on unknown options, :class:`~coverage_ros.errors.ConfigError` names a bad value."""
    args = build_parser().parse_args(attach_values(sys.argv[1:] if argv is None else argv))
    return config_from_args(args)


def check_out_folder(out: Path) -> None:
    """Refuse an ``--out`` that cannot be the run's folder: a file, under a file, or where no
    folder can be made."""
    if out.exists() and not out.is_dir():
        raise ConfigError.at("--out", "is a file, not a folder", str(out))
    parent = next((p for p in (out, *out.parents) if p.exists()), Path("."))
    if not parent.is_dir():
        raise ConfigError.at("--out", f"{parent} is a file, not a folder", str(out))
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError.at("--out", f"{parent} is not writable", str(out))


def _finite(option: str, value: float, low: float, strict: bool, unit: str) -> float:
    ok = math.isfinite(value) and (value > low if strict else value >= low)
    if not ok:
        raise ConfigError.at(option, f"must be {'>' if strict else '>='} {low:g} [{unit}]", value)
    return float(value)


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """:class:`RunConfig` of parsed options, each value checked (module docstring)."""
    if args.robots is not None and args.robots < 1:
        raise ConfigError.at("--robots", "must be >= 1", args.robots)
    if args.robots_per_process is not None and args.robots_per_process < 1:
        raise ConfigError.at("--robots-per-process", "must be >= 1", args.robots_per_process)
    duration = _finite("--duration", args.duration, 0.0, True, "s")
    clock_rate = _finite("--clock-rate", args.clock_rate, 0.0, False, "Hz")
    odom_rate = _finite("--odom-rate", args.odom_rate, 0.0, True, "Hz")
    rtf = args.rtf if args.rtf is not None else (0.0 if args.lockstep else 1.0)
    if not (math.isfinite(rtf) and rtf >= 0):
        raise ConfigError.at("--rtf", "must be >= 0 (0: as fast as possible)", rtf)
    control_rate = _finite("--control-rate", args.control_rate, 0.0, True, "Hz")
    if args.sensor_radius is not None:
        _finite("--sensor-radius", args.sensor_radius, 0.0, True, "m")
    # The strategy and its settings are checked here, before any process starts.
    choice = strategy_choice(args.strategy,
                             yaml_mapping(args.strategy_params, "--strategy-params"),
                             "--strategy-params", explore=args.explore)
    if args.map_free and (args.explore or choice.needs_map):
        raise ConfigError.at("--map-free", f"strategy {args.strategy} needs a map"
                             if choice.needs_map else "and --explore exclude each other", True,
                             "--strategy bvc without --explore")
    if args.until_explored is not None and not (args.explore and 0 < args.until_explored <= 1):
        raise ConfigError.at("--until-explored", "needs --explore and a fraction in (0, 1]",
                             args.until_explored)
    if args.until_settled is not None:
        if args.explore:
            raise ConfigError.at("--until-settled", "does not apply to --explore",
                                 args.until_settled, "--until-explored F")
        _finite("--until-settled", args.until_settled, 0.0, True, "s")
    region = Region(tuple(parse_region_text(t) for t in args.region))
    if args.explore and not region.everywhere:
        raise ConfigError.at("--region", "does not apply to --explore (the density is the "
                             "belief's entropy)", args.region)
    discovery = (parse_discovery_address(args.discovery_server)
                 if args.discovery_server is not None else None)
    if args.out is not None:
        check_out_folder(args.out)
    if args.viewer and sys.platform.startswith("linux") and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):  # (X11, Wayland)
        raise ConfigError.at("--viewer", "needs a display (DISPLAY or WAYLAND_DISPLAY is unset)",
                             expected="--serve-web (a browser) or --record (a file to open)")
    params = robot_params(args.robot_param)
    if "strategy" in params or "strategy_params" in params:  # (checked as --strategy is)
        strategy_choice(str(params.get("strategy", args.strategy)),
                        yaml_mapping(str(params.get("strategy_params", args.strategy_params)),
                                     "--robot-param strategy_params"),
                        "--robot-param strategy_params", explore=args.explore)
    return RunConfig(
        world=args.world, strategy=args.strategy, strategy_params=args.strategy_params,
        choice=choice, robots=args.robots, team_file=args.team, humans=tuple(args.human),
        explore=args.explore, map_free=args.map_free, until_explored=args.until_explored,
        until_settled=args.until_settled,
        duration=duration, seed=args.seed, starts=args.starts, lockstep=args.lockstep, rtf=rtf,
        out=args.out, record=args.record, viewer=args.viewer, serve_web=args.serve_web,
        domain_id=args.domain_id, control_rate=control_rate, update_load=args.update_load,
        state_rate=args.state_rate, clock_rate=clock_rate, odom_rate=odom_rate,
        sensor_radius=args.sensor_radius,
        robot_params=MappingProxyType(params),
        robots_per_process=args.robots_per_process, fork_server=not args.no_fork_server,
        kills=tuple(args.kill),
        restarts=tuple(args.restart), regions=tuple(args.region), region=region,
        markers=not args.no_markers, stats=args.stats, remote_robots=args.remote_robots,
        discovery=discovery,
        executor=args.executor or executor_kind(),  # a bad COVERAGE_ROS_EXECUTOR: refused
        quiet=args.quiet)
