"""What starting a team costs (``scripts/bench_startup``).

Runs ``coverage-team --lockstep`` for one second of sim time - almost all of such a run is its
start - with the robot processes forked from the launcher's preloaded interpreter (the default)
and started as new interpreters (``--no-fork-server``), in turn, ``--repeats`` times each, and
reports per setting the median CPU time of the launcher and everything it started [s] (the
children's rusage: every process is reaped inside the launcher's tree), the median wall time
of the whole command, their ratios, and whether the two ways gave the same summary
(:func:`~coverage_ros.cli.team.summary.deterministic_part`), and how many robot processes
were forked each way (the fork server's log). The last stdout line is JSON;
the rows replace ``docs/results/startup.json``'s rows of the same setting.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from coverage_ros.bench.environment import SANDBOX
from coverage_ros.bench.lockstep import TEAM, differences
from coverage_ros.bench.results import update_rows
from coverage_ros.cli.team.summary import deterministic_part

#: (world, robots) of each setting: up to 8 robots per core get a process each by default.
SETTINGS = (("office", 4), ("office", 8), (str(SANDBOX), 16))
ROW_KEY = ("world", "robots")


def children_cpu() -> float:
    """[s] user + system CPU time of this process's reaped children so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run(world: str, robots: int, forked: bool, out: Path
        ) -> tuple[float, float, dict, int]:
    """One launcher run: (CPU s, wall s, summary, how many robot processes the fork server
    says it started)."""
    cmd = TEAM + ["--quiet", "--lockstep", "--no-markers", "--world", world, "--robots",
                  str(robots), "--duration", "1", "--out", str(out)]
    cmd += [] if forked else ["--no-fork-server"]
    cpu0, wall0 = children_cpu(), time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    wall, cpu = time.monotonic() - wall0, children_cpu() - cpu0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    log = out / "logs" / "forkserver.log"
    return cpu, wall, json.loads((out / "summary.json").read_text()), \
        log.read_text().count(" is process ") if log.exists() else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=3, help="runs of each way per setting")
    ap.add_argument("--only", type=int, action="append", choices=range(len(SETTINGS)),
                    help=f"only setting K of {[f'{w} x {n}' for w, n in SETTINGS]}")
    ap.add_argument("--no-results", action="store_true",
                    help="do not write docs/results/startup.json")
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-startup-") as tmp:
        for k, (world, robots) in enumerate(SETTINGS):
            if args.only and k not in args.only:
                continue
            runs: dict[bool, list[tuple[float, float, dict, int]]] = {True: [], False: []}
            for r in range(args.repeats):
                for forked in (True, False):
                    out = Path(tmp) / f"{k}-{r}-{int(forked)}"
                    runs[forked].append(run(world, robots, forked, out))
                    print(f"[bench_startup] {Path(world).stem} x {robots}, "
                          f"{'forked' if forked else 'new interpreters'}: "
                          f"{runs[forked][-1][0]:.2f} CPU-s, {runs[forked][-1][1]:.2f} s wall",
                          file=sys.stderr, flush=True)
            cpu = {f: statistics.median(r[0] for r in runs[f]) for f in runs}
            wall = {f: statistics.median(r[1] for r in runs[f]) for f in runs}
            diff = differences(deterministic_part(runs[True][0][2]),
                               deterministic_part(runs[False][0][2]))
            rows.append({"world": Path(world).stem, "robots": robots,
                         "cpu_s_forked": round(cpu[True], 2),
                         "cpu_s_new_interpreters": round(cpu[False], 2),
                         "cpu_ratio": round(cpu[True] / cpu[False], 3),
                         "wall_s_forked": round(wall[True], 2),
                         "wall_s_new_interpreters": round(wall[False], 2),
                         "wall_ratio": round(wall[True] / wall[False], 3),
                         "same_summary": not diff, "repeats": args.repeats,
                         "forked_processes": [runs[f][0][3] for f in (True, False)]})
            print(f"[bench_startup] {Path(world).stem} x {robots}: CPU "
                  f"{rows[-1]['cpu_ratio']:.2f}x, wall {rows[-1]['wall_ratio']:.2f}x of new "
                  f"interpreters; same summary: {diff or 'yes'}",
                  file=sys.stderr, flush=True)
    if not args.no_results:
        update_rows("startup", rows, ROW_KEY, argv, "scripts/bench_startup")
    print(json.dumps({"rows": rows}))
    return 0 if all(r["same_summary"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
