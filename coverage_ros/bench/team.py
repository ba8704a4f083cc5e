"""Benchmark of a whole team in real time (``scripts/bench_team``).

Runs ``coverage-team`` (world node + the robots' processes, geodesic strategy by default) on
``../shared/maps/depot.yaml`` with 16 robots at real-time factor 1 (``--lockstep``: in
lock-step, as fast as the robots answer) and reports the team's achieved real-time factor, CPU
(% of one core) and memory per robot (all robot processes' figures over the number of robots),
and how often the robots updated their cells: the largest of the robots' median periods between
coverage updates, read back from their logs (each robot logs its update statistics when it
stops). ``--robots-per-process K``, ``--discovery-server`` and ``--executor`` are passed to the
launcher. Progress goes to stderr; the last stdout line is JSON, and the run's row (one per
setting: robots, processes, discovery, executor, lock-step, world, strategy) replaces the same
setting's row in ``docs/results/team.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import tempfile
from pathlib import Path

from coverage_ros.bench.environment import DEPOT
from coverage_ros.bench.results import update_rows
from coverage_ros.cli.team import main as team_main
from coverage_ros.nodes.runner import EXECUTORS

#: A real-time team keeps the clock: this real-time factor or more.
TARGET_RTF = 0.95
#: What makes a row of team.json a setting of its own.
ROW_KEY = ("robots", "robot_processes", "discovery", "executor", "lockstep", "world", "strategy")

#: A robot's update statistics line (nodes/update_worker.UpdateWorker.summary) in its log.
UPDATES = re.compile(r"\[robot_(\d+)\.coverage_robot\]: (\d+) coverage updates, one every "
                     r"(\S+) s wall \(median (\S+) s, longest (\S+) s\)")


def update_periods(log_dir: Path) -> dict[int, dict[str, float]]:
    """Each robot's update count and median / longest period [s wall] from the launcher's log
    folder (robot_<id>.log and robots_<a>-<b>.log alike)."""
    out = {}
    for log in sorted(log_dir.glob("robot*.log")):
        for m in UPDATES.finditer(log.read_text(errors="replace")):
            out[int(m.group(1))] = {"updates": int(m.group(2)), "median_s": float(m.group(4)),
                                    "longest_s": float(m.group(5))}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", type=int, default=16)
    ap.add_argument("--world", default=str(DEPOT))
    ap.add_argument("--strategy", default="geodesic")
    ap.add_argument("--duration", type=float, default=60.0, help="[s] sim time")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--robots-per-process", type=int, default=None, metavar="K",
                    help="robots per process (default: the launcher's for this machine)")
    ap.add_argument("--discovery-server", action="store_true",
                    help="a Fast DDS discovery server instead of simple discovery")
    ap.add_argument("--executor", choices=EXECUTORS, default=EXECUTORS[0],
                    help="rclpy executor of every node process (the launcher's --executor)")
    ap.add_argument("--keep", type=Path, help="keep the run's output folder here")
    ap.add_argument("--lockstep", action="store_true",
                    help="lock-step: the world waits for every robot each tick, as fast as they "
                    "answer (the rtf is what the team's work allows)")
    ap.add_argument("--rtf", type=float, default=None,
                    help="real-time factor (default 1; with --lockstep none: an upper bound)")
    ap.add_argument("--no-results", action="store_true",
                    help="do not write docs/results/team.json")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-team-") as tmp:
        out = args.keep or Path(tmp)
        extra = (["--robots-per-process", str(args.robots_per_process)]
                 if args.robots_per_process else []) + \
            (["--discovery-server"] if args.discovery_server else []) + \
            ["--executor", args.executor] + (["--lockstep"] if args.lockstep else []) + \
            (["--rtf", str(args.rtf)] if args.rtf is not None else
             [] if args.lockstep else ["--rtf", "1.0"])
        code = team_main(["--robots", str(args.robots), "--world", args.world, "--strategy",
                          args.strategy, "--duration", str(args.duration), "--seed",
                          str(args.seed), "--stats", "--out", str(out),
                          "--no-markers", *extra])
        if code != 0:
            return code
        summary = json.loads((out / "summary.json").read_text())
        periods = update_periods(out / "logs")
    procs = summary["processes"]
    medians = [p["median_s"] for p in periods.values() if math.isfinite(p["median_s"])]
    result = {
        "robots": args.robots, "world": Path(args.world).name, "strategy": args.strategy,
        "robot_processes": procs["robot_processes"],
        "discovery": "server" if args.discovery_server else "simple",
        "executor": args.executor, "lockstep": args.lockstep,
        "sim_time": round(summary["sim_time"] - (summary["ready_at"] or 0.0), 1),
        "rtf": summary["rtf"],
        "rss_mb_per_robot": procs["per_robot"]["rss_mb"],
        "cpu_percent_per_robot": procs["per_robot"]["cpu_percent"],
        "robot_process_rss_mb": procs["robot_mean"]["rss_mb_peak"],
        "update_period_worst_median_s": max(medians) if len(medians) == args.robots else None,
        "min_separation": summary["metrics"]["min_separation"],
        "robots_with_update_stats": len(periods),
        "world_cpu_percent": procs["per_process"]["world"]["cpu_percent"],
        "world_rss_mb": procs["per_process"]["world"]["rss_mb_peak"],
        "H_reduction": round(1 - summary["metrics"]["H"] / summary["metrics"]["H_start"], 3),
        "collisions": sum(r["collisions"] for r in summary["robots"]),
    }
    if not args.lockstep and not args.no_results:
        # A real-time team keeps up with the clock and touches nothing (lock-step runs have no
        # such target: their pace is what the robots' work allows).
        result["target"] = f"rtf >= {TARGET_RTF}, no collision"
        result["met"] = result["rtf"] >= TARGET_RTF and result["collisions"] == 0
    if not args.no_results:
        update_rows("team", [result], ROW_KEY, argv, "scripts/bench_team")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
