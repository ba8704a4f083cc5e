"""Benchmark of a whole team in real time (``scripts/bench_team``).

Runs ``coverage-team`` (world node + one robot process per robot, geodesic strategy by
default) on ``../shared/maps/depot.yaml`` with 16 robots at real-time factor 1 and reports the
team's achieved real-time factor, and CPU (% of one core) and peak memory per robot process.
Progress goes to stderr; the last stdout line is JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from coverage_ros.cli.team import main as team_main

DEPOT = Path(__file__).resolve().parents[2].parent / "shared" / "maps" / "depot.yaml"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", type=int, default=16)
    ap.add_argument("--world", default=str(DEPOT))
    ap.add_argument("--strategy", default="geodesic")
    ap.add_argument("--duration", type=float, default=60.0, help="[s] sim time")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-team-") as tmp:
        out = Path(tmp)
        code = team_main(["--robots", str(args.robots), "--world", args.world, "--strategy",
                          args.strategy, "--duration", str(args.duration), "--seed",
                          str(args.seed), "--rtf", "1.0", "--stats", "--out", str(out)])
        if code != 0:
            return code
        summary = json.loads((out / "summary.json").read_text())
    procs = summary["processes"]
    result = {
        "robots": args.robots, "world": Path(args.world).name, "strategy": args.strategy,
        "sim_time": round(summary["sim_time"] - (summary["ready_at"] or 0.0), 1),
        "rtf": summary["rtf"],
        "robot_cpu_percent": procs["robot_mean"]["cpu_percent"],
        "robot_rss_mb": procs["robot_mean"]["rss_mb_peak"],
        "world_cpu_percent": procs["per_process"]["world"]["cpu_percent"],
        "world_rss_mb": procs["per_process"]["world"]["rss_mb_peak"],
        "H_reduction": round(1 - summary["metrics"]["H"] / summary["metrics"]["H_start"], 3),
        "collisions": sum(r["collisions"] for r in summary["robots"]),
    }
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
