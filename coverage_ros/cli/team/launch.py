"""coverage-team: run a coverage team - the world node and one robot process per robot.

    coverage-team --robots 6 --world office --strategy geodesic --duration 60 --record

Starts ``world_node``, the robots' processes, ``marker_node`` (RViz markers; ``--no-markers``)
and ``rerun_bridge`` (when recording or viewing) as separate processes running what ``ros2 run``
would (the robots forked from a preloaded interpreter: :mod:`.forkserver`), with discovery
limited to this machine and a fresh ``ROS_DOMAIN_ID``; shows progress (sim time, coverage
cost); stops everything in order at the end or on Ctrl-C; writes ``<out>/summary.json`` and
prints a table.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import time
from pathlib import Path

from coverage_ros.cli.interrupts import Interrupts
from coverage_ros.cli.team.domains import acquire_domain
from coverage_ros.cli.team.monitor import TeamMonitor
from coverage_ros.cli.team.network import (
    remote_command,
    start_discovery_server,
    write_remote_script,
)
from coverage_ros.cli.team.options import RunConfig, parse_config
from coverage_ros.cli.team.plan import MONITOR_ENV, RunPlan, plan_run
from coverage_ros.cli.team.processes import ProcessSet, executable, ros_args
from coverage_ros.cli.team.summary import RunLog, picture, summarize, summary_table
from coverage_ros.core.world import write_team
from coverage_ros.errors import ConfigError, CoverageError
from coverage_ros.nodes.shm_ports import warn_removed_ports

#: [s] wall time the children get to stop cleanly after an interrupt before SIGTERM, then SIGKILL
#: (everything is gone within 10 s).
INTERRUPT_GRACE = 4.0


def main(argv: list[str] | None = None) -> int:
    try:
        config = parse_config(argv)
        plan = plan_run(config, config.out or Path("out") / time.strftime("team-%Y%m%d-%H%M%S"))
        return run(plan)
    except CoverageError as exc:
        print(f"coverage-team: error: {exc}", file=sys.stderr)
        return 2


#: What a run writes in its folder (besides logs/, params/ and remote/, cleared too).
RUN_FILES = ("team.yaml", "summary.json", "summary.png", "recording.rrd", "explored_map.yaml",
             "explored_map.pgm")


def clear_previous_run(out: Path) -> bool:
    """Remove what an earlier run left in ``out`` (:data:`RUN_FILES`, its logs, params and
    remote scripts) so that no file of it passes for this run's; whether there was one."""
    old = [out / name for name in RUN_FILES if (out / name).is_file()]
    for sub in ("logs", "params", "remote"):
        if (out / sub).is_dir():
            old += [p for p in (out / sub).iterdir() if p.is_file()]
    for path in old:
        path.unlink()
    return bool(old)


def _sayer(config: RunConfig):
    if config.quiet:
        return lambda *_: None
    return lambda m: print(m, file=sys.stderr, flush=True)


def run(plan: RunPlan) -> int:
    """Start the planned run, follow it to its end (or an interrupt), stop it, report."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    config, out = plan.config, plan.out
    say = _sayer(config)
    warn_removed_ports("coverage-team")  # (before the domain probe starts ROS)
    # One DDS domain per run, for sure: held until this process exits.
    domain_lock = acquire_domain(config.domain_id)
    env = plan.environment(os.environ, domain_lock.domain_id)
    for key in MONITOR_ENV:  # the launcher's own monitor node joins the same domain
        if key in env:
            os.environ[key] = env[key]
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # (before any process starts)
        raise ConfigError.at("--out", f"cannot make the folder ({exc.strerror})",
                             str(out)) from None
    if clear_previous_run(out):
        say(f"coverage-team: {out} held an earlier run: its outputs were removed")
    (out / "logs").mkdir(exist_ok=True)
    write_team(out / "team.yaml", plan.team)
    for proc in plan.processes:
        if proc.params_file is not None:
            proc.params_file.parent.mkdir(parents=True, exist_ok=True)
            proc.params_file.write_text(proc.params_text)
    reach = (f"server {env['ROS_DISCOVERY_SERVER']}" if config.discovery is not None
             else env["ROS_AUTOMATIC_DISCOVERY_RANGE"])
    say(f"coverage-team: {plan.robots} x {config.strategy} on {plan.world_path} for "
        f"{config.duration:g} s sim time (ROS_DOMAIN_ID={domain_lock.domain_id}, discovery "
        f"{reach}); output in {out}")
    for note in plan.notes:
        print(f"coverage-team: {note}", file=sys.stderr, flush=True)

    procs = ProcessSet(env, out / "logs", fork_server=config.fork_server and any(
        p.ids[0] not in plan.remote for p in plan.processes))
    interrupted = False
    failure = None
    monitor = None
    # The launcher handles SIGINT itself (children stopped, a summary written): rclpy's
    # handler would shut the context down under the monitor's spin instead.
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    # From the first process on, SIGINT and SIGTERM end the run the same way: children stopped
    # (SIGKILL on their process groups at the end), a summary of what was measured, one line.
    stop = Interrupts()
    t_wall0 = time.monotonic()
    try:
        if config.discovery is not None:
            start_discovery_server(procs, config.discovery)
        monitor = TeamMonitor(plan, procs, say,
                              relaunch=lambda rid: procs.start_again(f"robot_{rid}"))
        # Robots first: they load while the world starts, then wait for /map and /clock.
        for proc in plan.processes:
            if proc.ids[0] in plan.remote:  # printed even with --quiet: someone has to run it
                rid = proc.ids[0]
                script = write_remote_script(out / "remote" / f"robot_{rid}.sh", env, proc.cmd)
                print(f"coverage-team: start robot {rid} on its host ({script}):\n  "
                      f"{remote_command(env, proc.cmd)}", file=sys.stderr, flush=True)
            else:
                procs.start(proc.name, proc.cmd)
        procs.start("world", plan.world_command())
        _start_viz(plan, procs, say)
        if config.markers:
            procs.start("markers", executable("marker_node") + ros_args(use_sim_time=True))
        monitor.run()
    except (KeyboardInterrupt, RuntimeError) as exc:
        interrupted = stop.caused(exc)
        if not interrupted:
            failure = str(exc)
    finally:
        stop.ignore()  # a second Ctrl-C must not cut the clean-up short
        if interrupted:
            procs.stop(timeout=INTERRUPT_GRACE)  # all at once: nothing left within 10 s
        else:
            procs.stop([n for n in procs.children if n.startswith(("robot_", "robots_"))])
            procs.stop(["bridge"], timeout=30.0)  # let the recording be closed and indexed
            procs.stop(["world"])
            procs.stop([n for n in procs.children if n != "viewer"])
        stop.restore()
    wall = time.monotonic() - t_wall0
    try:
        log = monitor.finish() if monitor is not None else None
        code = _report(plan, monitor, log, procs, wall, interrupted, failure, say)
        _close_viewer(procs, say, interrupted or failure is not None)
        return code
    finally:
        procs.close()
        if monitor is not None:
            monitor.destroy_node()
        rclpy.try_shutdown()
        domain_lock.release()


def _report(plan: RunPlan, monitor: TeamMonitor | None, log: RunLog | None, procs: ProcessSet,
            wall: float, interrupted: bool, failure: str | None, say) -> int:
    """The summary and the lines that end a run (one line when interrupted)."""
    config, out = plan.config, plan.out
    if failure is not None:
        print(f"coverage-team: error: {failure}", file=sys.stderr)
        return 1
    if monitor is None or log is None:
        print("coverage-team: interrupted before the team started", file=sys.stderr)
        return 130
    if log.sim_time <= 0 and not interrupted:
        for child in procs.failed():
            say(f"  {child.name} exited with {child.popen.returncode}:\n{procs.tail(child)}")
        return 1
    summary = summarize(log, plan.team, plan.world, monitor.domain, config.strategy,
                        config.seed, wall, interrupted).as_dict()
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    if interrupted:
        print(f"coverage-team: interrupted at sim time {log.sim_time:.1f} s; wrote "
              f"{out / 'summary.json'} (\"interrupted\": true)", file=sys.stderr)
        return 130
    if monitor.exploration is not None:
        say(f"  explored map: {monitor.exploration.write_map(out)}")
    picture(out / "summary.png", log, plan.team, plan.world, monitor.domain, config.strategy)
    if not config.quiet:
        print(summary_table(summary))
    say(f"coverage-team: wrote {out / 'summary.json'} and {out / 'summary.png'}; logs in "
        f"{out / 'logs'}")
    if config.record:
        say(f"  recording: {out / 'recording.rrd'}  (open it with: rerun {out / 'recording.rrd'})")
    return 0


def _start_viz(plan: RunPlan, procs: ProcessSet, say) -> None:
    """The rerun bridge, and the viewer (a child like the others) if asked for."""
    config = plan.config
    if not config.visualized:
        return
    from coverage_ros.viz.web_viewer import free_ports, grpc_proxy_url, web_viewer_url

    params = plan.bridge_params()
    # Ports the kernel says are free now: a second run's viewer never collides with the first.
    viewer_port, grpc_port, web_port = free_ports(3)
    if config.viewer:
        rerun = Path(sys.executable).with_name("rerun")
        procs.start("viewer", [str(rerun), "--port", str(viewer_port), "--bind", "127.0.0.1"])
        params["connect_url"] = grpc_proxy_url(viewer_port)
        say(f"  rerun viewer started (port {viewer_port})")
    if config.serve_web:
        params.update(serve_web=True, grpc_port=grpc_port, web_port=web_port)
        # Printed even with --quiet: without it nobody finds the viewer.
        print(f"coverage-team: web viewer at {web_viewer_url(web_port, grpc_port)}",
              file=sys.stderr, flush=True)
    procs.start("bridge", executable("rerun_bridge") + ros_args(**params))


def _close_viewer(procs: ProcessSet, say, at_once: bool) -> None:
    """The run is over: the viewer stays open until the user closes it (Ctrl-C closes it
    too), since nothing the launcher starts outlives it; at once after an interrupt."""
    viewer = procs.children.get("viewer")
    if viewer is None or not viewer.alive:
        return
    if not at_once:
        say("coverage-team: the rerun viewer stays open: close it (or Ctrl-C) to finish")
        with contextlib.suppress(KeyboardInterrupt):
            viewer.popen.wait()
    procs.stop(["viewer"], timeout=INTERRUPT_GRACE)


if __name__ == "__main__":
    sys.exit(main())
