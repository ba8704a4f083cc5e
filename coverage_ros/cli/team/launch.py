"""coverage-team: run a coverage team - the world node and one robot process per robot.

    coverage-team --robots 6 --world office --strategy geodesic --duration 60 --record

Starts ``world_node``, ``robot_node`` x N, ``marker_node`` (RViz markers; ``--no-markers``) and
``rerun_bridge`` (when recording or viewing) as separate processes, exactly as ``ros2 run``
would, with discovery limited to this machine and a fresh ``ROS_DOMAIN_ID``; shows progress
(sim time, coverage cost); stops everything cleanly at the end or on Ctrl-C; writes
``<out>/summary.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import signal
import sys
import time
from pathlib import Path

from coverage_ros.cli.arguments import attach_values
from coverage_ros.cli.team.domains import acquire_domain
from coverage_ros.cli.team.lockstep import OBSERVER
from coverage_ros.cli.team.members import build_team
from coverage_ros.cli.team.monitor import TeamTracker
from coverage_ros.cli.team.network import (
    check_reach,
    discovery_advice,
    parse_discovery_address,
    parse_remote_robots,
    remote_command,
    start_discovery_server,
    write_remote_script,
)
from coverage_ros.cli.team.options import build_parser, parse_faults
from coverage_ros.cli.team.processes import ProcessSet, executable, ros_args
from coverage_ros.cli.team.robots import (
    default_robots_per_process,
    plan_processes,
    robot_params,
    spec_parameters,
    team_rates,
)
from coverage_ros.cli.team.summary import summary_table
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.strategies import strategy_choice
from coverage_ros.core.world import load_planar_world, write_team
from coverage_ros.core.world.region import Region, parse_region_text
from coverage_ros.core.world.yaml_io import yaml_mapping
from coverage_ros.errors import ConfigError, CoverageError
from coverage_ros.nodes.runner import EXECUTOR_ENV, executor_kind
from coverage_ros.worlds import resolve_world_path

#: [s] wall time the children get to stop cleanly after an interrupt before SIGTERM, then SIGKILL
#: (everything is gone within 10 s).
INTERRUPT_GRACE = 4.0
#: Robots per core that bench_team ran at real time (64 on 2 cores, robots sharing processes).
REAL_TIME_ROBOTS_PER_CORE = 32
STARTUP_TIMEOUT = 90.0  # [s] wall time for the world and robots to come up (16 robots, 2 cores)
REMOTE_STARTUP_TIMEOUT = 600.0  # [s] ... when robots on other hosts are started by hand
PROGRESS_PERIOD = 0.5  # [s] wall time between progress refreshes
#: [s] wall time between coverage cost evaluations for the progress bar (a tessellation of a
#: large map costs ~0.5 s of CPU that the robots need more).
METRICS_PERIOD = 10.0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(attach_values(sys.argv[1:] if argv is None else argv))
    try:
        return run(args)
    except CoverageError as exc:
        print(f"coverage-team: error: {exc}", file=sys.stderr)
        return 2


def run(args: argparse.Namespace) -> int:
    if args.robots is not None and args.robots < 1:
        raise ConfigError.at("--robots", "must be >= 1", args.robots)
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise ConfigError.at("--duration", "must be > 0 [s]", args.duration)
    if not (math.isfinite(args.clock_rate) and args.clock_rate >= 0):
        raise ConfigError.at("--clock-rate", "must be >= 0 [Hz]", args.clock_rate)
    if not (math.isfinite(args.odom_rate) and args.odom_rate > 0):
        raise ConfigError.at("--odom-rate", "must be > 0 [Hz]", args.odom_rate)
    if args.rtf is None:
        args.rtf = 0.0 if args.lockstep else 1.0  # lock-step: as fast as the robots answer
    if not (math.isfinite(args.rtf) and args.rtf >= 0):
        raise ConfigError.at("--rtf", "must be >= 0 (0: as fast as possible)", args.rtf)
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
    world_path = resolve_world_path(args.world, "--world")
    world = load_planar_world(world_path, "--world")
    team = build_team(world, args)  # refuses teams the map or the machine cannot hold
    args.robots = len(team)
    specs = [m.spec for m in team]
    radius = max(s.radius for s in specs)
    faults = parse_faults(args.kill, args.restart, args.robots)
    remote = parse_remote_robots(args.remote_robots, args.robots)
    if any(rid in remote for _, rid, _ in faults):
        raise ConfigError.at("--kill/--restart", "cannot reach a robot on another host",
                             sorted({rid for _, rid, _ in faults if rid in remote}))
    discovery = (parse_discovery_address(args.discovery_server)
                 if args.discovery_server is not None else None)
    args.executor = args.executor or executor_kind()  # a bad COVERAGE_ROS_EXECUTOR: refused
    check_reach(dict(os.environ), remote, discovery is not None)
    per_process = (args.robots_per_process if args.robots_per_process is not None
                   else default_robots_per_process(args.robots))
    if per_process < 1:
        raise ConfigError.at("--robots-per-process", "must be >= 1", per_process)
    load, state_rate = team_rates(args.robots, per_process, args.update_load, args.state_rate)
    extra = robot_params(args.robot_param)
    region = Region(tuple(parse_region_text(t) for t in args.region))
    if args.explore and not region.everywhere:
        raise ConfigError.at("--region", "does not apply to --explore (the density is the "
                             "belief's entropy)", args.region)
    domain = world_domain(world, radius)  # the launcher's scoring
    region.restrict(domain.density, world.grid, domain.free, "--region")  # refused if empty
    # One DDS domain per run, for sure: held until this process exits.
    domain_lock = acquire_domain(args.domain_id)
    domain_id = domain_lock.domain_id
    out = args.out or Path("out") / time.strftime("team-%Y%m%d-%H%M%S")
    out.mkdir(parents=True, exist_ok=True)
    (out / "logs").mkdir(exist_ok=True)
    write_team(out / "team.yaml", team)
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["PYTHONUNBUFFERED"] = "1"
    env[EXECUTOR_ENV] = args.executor
    if discovery is not None:
        env["ROS_DISCOVERY_SERVER"] = "{}:{}".format(*discovery)
        env["ROS_SUPER_CLIENT"] = "TRUE"  # robots find neighbours in the graph: see all of it
    # The launcher's own monitor node joins the same domain.
    for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DISCOVERY_SERVER",
                "ROS_SUPER_CLIENT"):
        if key in env:
            os.environ[key] = env[key]
    say = (lambda *_: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    reach = (f"server {env['ROS_DISCOVERY_SERVER']}" if discovery is not None
             else env["ROS_AUTOMATIC_DISCOVERY_RANGE"])
    say(f"coverage-team: {args.robots} x {args.strategy} on {world_path} for {args.duration:g} "
        f"s sim time (ROS_DOMAIN_ID={domain_id}, discovery {reach}); output in {out}")
    params = {m.id: {"robot_id": m.id, "use_sim_time": True, "strategy": args.strategy,
                     "world": str(world_path), "control_rate": float(args.control_rate),
                     "update_load": float(load), "state_rate": float(state_rate),
                     "explore": bool(args.explore),
                     "strategy_params": args.strategy_params,
                     "manual": m.role == "human", "map_free": bool(args.map_free),
                     "team_size": len(team), "lockstep": bool(args.lockstep),
                     "region": "|".join(args.region),
                     **spec_parameters(m.spec), **extra} for m in team}
    processes = plan_processes(params, per_process, {rid for _, rid, _ in faults} |
                               set(remote), out / "params")
    # Participants: the robot processes (here or on other hosts), the world, the launcher, the
    # bridge and the markers.
    participants = len(processes) + 2 + int(bool(
        args.record or args.viewer or args.serve_web)) + int(not args.no_markers)
    if (advice := discovery_advice(participants, discovery is not None)) is not None:
        print(f"coverage-team: {advice}", file=sys.stderr, flush=True)
    cores = os.cpu_count() or 1
    if args.robots > REAL_TIME_ROBOTS_PER_CORE * cores and args.rtf >= 1.0 and \
            not args.lockstep:
        print(f"coverage-team: warning: {args.robots} robots on {cores} cores: beyond the "
              f"{REAL_TIME_ROBOTS_PER_CORE} per core measured at real time (scripts/bench_team)"
              "; the run may fall behind and robots lag their commands (--rtf below 1 keeps "
              "it in step)", file=sys.stderr, flush=True)

    procs = ProcessSet(env, out / "logs")
    interrupted = False
    failure = None
    tracker = viewer = None
    # From the first process on, SIGINT and SIGTERM end the run the same way: children stopped
    # (SIGKILL on their process groups at the end), a summary of what was measured, one line.
    handlers = {sig: signal.signal(sig, _signal_as_interrupt)
                for sig in (signal.SIGINT, signal.SIGTERM)}
    t_wall0 = time.monotonic()
    try:
        if discovery is not None:
            start_discovery_server(procs, discovery)
        commands = {p.ids[0]: p.cmd for p in processes if len(p.ids) == 1}
        tracker = TeamTracker(domain, world, team, args, faults, procs, say, region,
                              relaunch=lambda rid: procs.start(f"robot_{rid}", commands[rid],
                                                               append=True),
                              process_of={rid: p.name for p in processes for rid in p.ids})
        # Robots first: they load while the world starts, then wait for /map and /clock.
        for proc in processes:
            if proc.ids[0] in remote:  # printed even with --quiet: someone has to run it
                rid = proc.ids[0]
                script = write_remote_script(out / "remote" / f"robot_{rid}.sh", env, proc.cmd)
                print(f"coverage-team: start robot {rid} on its host ({script}):\n  "
                      f"{remote_command(env, proc.cmd)}", file=sys.stderr, flush=True)
            else:
                procs.start(proc.name, proc.cmd)
        startup = REMOTE_STARTUP_TIMEOUT if remote else STARTUP_TIMEOUT
        procs.start("world", executable("world_node") + ros_args(
            world=str(world_path), team=str((out / "team.yaml").resolve()), seed=args.seed,
            real_time_factor=float(args.rtf), clock_rate_hz=float(args.clock_rate),
            odom_rate_hz=float(args.odom_rate), status_rate_hz=2.0,
            publish_map=not args.explore, lockstep=bool(args.lockstep),
            lockstep_observers=OBSERVER, lockstep_start_timeout=startup + 30.0))
        viewer = _start_viz(args, procs, out, radius, world_path, say)
        if not args.no_markers:
            procs.start("markers", executable("marker_node") + ros_args(use_sim_time=True))
        tracker.run(startup, PROGRESS_PERIOD, METRICS_PERIOD)
    except KeyboardInterrupt:
        interrupted = True
    except RuntimeError as exc:
        failure = str(exc)
    finally:
        # A second Ctrl-C must not cut the clean-up short.
        for sig in handlers:
            signal.signal(sig, signal.SIG_IGN)
        if interrupted:
            procs.stop(timeout=INTERRUPT_GRACE)  # all at once: nothing left within 10 s
        else:
            robots = [n for n in procs.children if n.startswith("robot_")]
            procs.stop(robots)
            procs.stop(["bridge"], timeout=30.0)  # let the recording be closed and indexed
            procs.stop(["world"])
            procs.stop()
        for sig, previous in handlers.items():
            signal.signal(sig, previous)
    wall = time.monotonic() - t_wall0
    try:
        return _report(args, out, tracker, procs, viewer, wall, interrupted, failure, say)
    finally:
        if tracker is not None:
            tracker.close()
        domain_lock.release()


def _report(args, out: Path, tracker, procs: ProcessSet, viewer, wall: float,
            interrupted: bool, failure: str | None, say) -> int:
    """The summary and the lines that end a run (one line when interrupted)."""
    if failure is not None:
        print(f"coverage-team: error: {failure}", file=sys.stderr)
        return 1
    if tracker is None:
        print("coverage-team: interrupted before the team started", file=sys.stderr)
        return 130
    if tracker.sim_time <= 0 and not interrupted:
        for child in procs.failed():
            say(f"  {child.name} exited with {child.popen.returncode}:\n{procs.tail(child)}")
        return 1
    summary = tracker.summary(wall, interrupted)
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    if interrupted:
        print(f"coverage-team: interrupted at sim time {tracker.sim_time:.1f} s; wrote "
              f"{out / 'summary.json'} (\"interrupted\": true)", file=sys.stderr)
        return 130
    if tracker.exploration is not None:
        say(f"  explored map: {tracker.exploration.write_map(out)}")
    tracker.picture(out / "summary.png")
    if not args.quiet:
        print(summary_table(summary))
    say(f"coverage-team: wrote {out / 'summary.json'} and {out / 'summary.png'}; logs in "
        f"{out / 'logs'}")
    if args.record:
        say(f"  recording: {out / 'recording.rrd'}  (open it with: rerun {out / 'recording.rrd'})")
    if viewer is not None:
        with contextlib.suppress(Exception):
            viewer.wait(timeout=0)
    return 0


def _signal_as_interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def _start_viz(args, procs: ProcessSet, out: Path, radius: float, world_path: Path, say):
    """The rerun bridge (and viewer) if asked for; returns the viewer process or None."""
    if not (args.record or args.viewer or args.serve_web):
        return None
    import subprocess

    params = {"robot_radius": radius, "world": str(world_path), "use_sim_time": True,
              "explore": bool(args.explore)}
    viewer = None
    if args.record:
        params["record_path"] = str((out / "recording.rrd").resolve())
    from coverage_ros.viz.web_viewer import free_ports, grpc_proxy_url, web_viewer_url

    # Ports the kernel says are free now: a second run's viewer never collides with the first.
    viewer_port, grpc_port, web_port = free_ports(3)
    if args.viewer:
        rerun = Path(sys.executable).with_name("rerun")
        viewer = subprocess.Popen([str(rerun), "--port", str(viewer_port), "--bind",
                                   "127.0.0.1"], stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL, start_new_session=True)
        params["connect_url"] = grpc_proxy_url(viewer_port)
        say(f"  rerun viewer started (port {viewer_port})")
    if args.serve_web:
        params.update(serve_web=True, grpc_port=grpc_port, web_port=web_port)
        # Printed even with --quiet: without it nobody finds the viewer.
        print(f"coverage-team: web viewer at {web_viewer_url(web_port, grpc_port)}",
              file=sys.stderr, flush=True)
    procs.start("bridge", executable("rerun_bridge") + ros_args(**params))
    return viewer


if __name__ == "__main__":
    sys.exit(main())
