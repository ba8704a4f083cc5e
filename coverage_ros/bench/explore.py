"""Benchmark of exploring unknown maps (``scripts/bench_explore``).

1. The inverse sensor model: one 360-beam, 3.5 m scan on 5 cm cells, the vectorized model
   against the per-beam reference, median over many scans (target: <= 2 ms).
2. Coordinated exploration against the frontier baseline, offline (the robots' own controllers
   on a simulator, :mod:`coverage_ros.core.offline.exploration`): for each world, team size and
   seed (the same start cluster for every method), the sim time until 50 / 90 / 95 / 99 % of
   the reachable free area is explored. Methods: ``geodesic:paper`` (Bhattacharya et al. 2014,
   Sec. 4.2 as written), ``geodesic:nearest`` (the same cells, each robot heading for the
   nearest unexplored vertex of its own cell), ``frontier`` (explore_lite's choice, no
   coordination). A run that never reaches a level counts as the time limit for the averages.
3. With ``--live``: one ``coverage-team --explore`` run per method on the office world, for the
   record.

Progress goes to stderr; the last stdout line is JSON; each world, team size and method's
row replaces that setting's row in ``docs/results/explore.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from coverage_ros.bench.environment import REPO

SHARED_MAPS = REPO.parent / "shared" / "maps"
#: The worlds of the default run: the shipped worlds with rooms or obstacles, and the shared
#: map_server maps (warehouse.yaml, 1.7 million cells at 3 cm, is left out by default: a run
#: takes hours; ask for it with --worlds).
DEFAULT_WORLDS = ("office", "l_shape", "u_shape", "field", "tb3_sandbox", "depot")
METHODS = ("geodesic:paper", "geodesic:nearest", "frontier")
LEVELS = {"0.5": "t50", "0.9": "t90", "0.95": "t95", "0.99": "t99"}
#: The coordinated method must reach 95 % this much sooner than the baseline, on average.
TARGET_RATIO = 0.7


def world_path(name: str) -> Path:
    shipped = REPO / "config" / "worlds" / f"{name}.yaml"
    return shipped if shipped.is_file() else SHARED_MAPS / f"{name}.yaml"


def bench_sensor_model(scans: int = 200) -> dict:
    from coverage_ros.core.exploration.sensor_model import reference_scan_cells, scan_cells
    from coverage_ros.core.world.grid import GridMap
    from coverage_ros.core.world.robot import LidarSpec

    lidar = LidarSpec()  # 360 beams, 3.5 m
    lattice = GridMap(np.full((300, 300), -1, np.int8), 0.05)
    rng = np.random.default_rng(0)
    fast, slow = [], []
    for k in range(scans):
        ranges = rng.uniform(0.3, 4.5, lidar.beams)
        ranges[ranges > lidar.range_max] = np.inf  # about a quarter: no return
        pose = np.array([7.5 + rng.uniform(-1, 1), 7.5 + rng.uniform(-1, 1), rng.uniform(-3, 3)])
        args = (lattice, pose, ranges, lidar.angle_min, lidar.angle_increment, lidar.range_min,
                lidar.range_max)
        t0 = time.perf_counter()
        scan_cells(*args)
        fast.append(time.perf_counter() - t0)
        if k % 10 == 0:
            t0 = time.perf_counter()
            reference_scan_cells(*args)
            slow.append(time.perf_counter() - t0)
    ms, ref = 1e3 * float(np.median(fast)), 1e3 * float(np.median(slow))
    return {"ms": round(ms, 3), "reference_ms": round(ref, 2), "speedup": round(ref / ms, 1),
            "target_ms": 2.0, "met": ms <= 2.0}


def run_case(case: tuple[str, int, int, str, float]) -> dict:
    """One offline exploration run (in a worker process)."""
    from coverage_ros.core.offline.exploration import ExplorationConfig, run_exploration
    from coverage_ros.core.strategies import strategy_choice
    from coverage_ros.core.world import cluster_starts, load_world

    name, robots, seed, method, duration = case
    world = load_world(world_path(name))
    specs = [world.robot_spec(i) for i in range(robots)]
    starts = cluster_starts(world.grid, robots, max(s.radius for s in specs),
                            np.random.default_rng(seed))
    strategy, _, variant = method.partition(":")
    choice = strategy_choice(strategy, {"variant": variant} if variant else {}, explore=True)
    t0 = time.perf_counter()
    run = run_exploration(world.grid, choice, starts, specs,
                          ExplorationConfig(duration=duration, settle=False,
                                            until_explored=0.99))
    return {"world": name, "robots": robots, "seed": seed, "method": method,
            "explored_at": run.explored_at, "explored": round(float(run.explored[-1]), 4),
            "false_free": round(float(run.false_free[-1]), 5), "collisions": run.collisions,
            "sim_time": round(run.sim_time, 1), "wall_s": round(time.perf_counter() - t0, 1)}


def summarize(rows: list[dict], duration: float) -> dict:
    """Mean time to each level per (world, robots, method) and, per case, the coordinated
    methods' time to 95 % over the baseline's."""
    def t(row: dict, level: str) -> float:
        v = row["explored_at"].get(level)
        return duration if v is None else float(v)

    groups: dict[tuple[str, int], dict[str, list[dict]]] = {}
    for r in rows:
        groups.setdefault((r["world"], r["robots"]), {}).setdefault(r["method"], []).append(r)
    table: list[dict] = []
    ratios: dict[str, list[float]] = {m: [] for m in METHODS if m != "frontier"}
    for (world, robots), by_method in sorted(groups.items()):
        base = by_method.get("frontier", [])
        base95 = {r["seed"]: t(r, "0.95") for r in base}
        for method, runs in sorted(by_method.items()):
            entry = {"world": world, "robots": robots, "method": method,
                     **{key: round(float(np.mean([t(r, lv) for r in runs])), 1)
                        for lv, key in LEVELS.items()},
                     "reached_95": sum(r["explored_at"].get("0.95") is not None for r in runs),
                     "runs": len(runs), "collisions": sum(r["collisions"] for r in runs),
                     "false_free_max": max(r["false_free"] for r in runs)}
            if method != "frontier" and base95:
                per_seed = [t(r, "0.95") / base95[r["seed"]] for r in runs
                            if r["seed"] in base95]
                entry["ratio_95"] = round(float(np.mean(per_seed)), 3)
                ratios[method].extend(per_seed)
            table.append(entry)
    overall = {m: round(float(np.mean(v)), 3) for m, v in ratios.items() if v}
    best = min(overall, key=lambda m: overall[m]) if overall else None
    return {"table": table, "ratio_95_mean": overall, "best": best,
            "target": f"coordinated time to 95 % <= {TARGET_RATIO} x the frontier baseline's",
            "met": bool(best is not None and overall[best] <= TARGET_RATIO)}


def live_runs(robots: int, duration: float, seed: int) -> list[dict]:
    """One coverage-team --explore run per method, for the record."""
    from coverage_ros.cli.team import main as team_main

    out = []
    for method in METHODS:
        strategy, _, variant = method.partition(":")
        with tempfile.TemporaryDirectory(prefix="bench-explore-") as tmp:
            args = ["--explore", "--world", "office", "--robots", str(robots), "--strategy",
                    strategy, "--duration", str(duration), "--seed", str(seed), "--out", tmp,
                    "--until-explored", "0.99", "--quiet"]
            if variant:
                args += ["--robot-param", f"strategy_params:={{variant: {variant}}}"]
            code = team_main(args)
            if code != 0:
                out.append({"method": method, "error": code})
                continue
            summary = json.loads((Path(tmp) / "summary.json").read_text())
        ex = summary["exploration"]
        out.append({"method": method, "explored_at": ex["explored_at"],
                    "explored": ex["explored_fraction"], "false_free": ex["false_free"],
                    "collisions": sum(r["collisions"] for r in summary["robots"]),
                    "rtf": summary["rtf"]})
        print(f"  live {method}: {out[-1]}", file=sys.stderr, flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", default=",".join(DEFAULT_WORLDS))
    ap.add_argument("--robots", type=int, nargs="+", default=[4, 8])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--duration", type=float, default=900.0, help="[s] sim time limit per run")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--live", action="store_true", help="also one live team run per method")
    ap.add_argument("--no-sensor", action="store_true", help="skip the sensor model timing")
    ap.add_argument("--no-results", action="store_true",
                    help="do not update docs/results/explore.json")
    args = ap.parse_args(argv)
    result: dict = {}
    if not args.no_sensor:
        result["sensor_model"] = bench_sensor_model()
        print(f"inverse sensor model: {result['sensor_model']}", file=sys.stderr, flush=True)
    worlds = [w for w in args.worlds.split(",") if w]
    missing = [w for w in worlds if not world_path(w).is_file()]
    if missing:
        print(f"skipping worlds not found: {missing} (shared maps live in {SHARED_MAPS})",
              file=sys.stderr)
    cases = [(w, n, s, m, args.duration) for w in worlds if w not in missing
             for n in args.robots for s in args.seeds for m in args.methods.split(",")]
    rows = []
    t0 = time.monotonic()
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        for k, row in enumerate(pool.map(run_case, cases), 1):
            rows.append(row)
            print(f"  [{k}/{len(cases)}, {time.monotonic() - t0:.0f} s] {row['world']} "
                  f"{row['robots']} robots seed {row['seed']} {row['method']}: 95 % at "
                  f"{row['explored_at']['0.95']} s, 99 % at {row['explored_at']['0.99']} s "
                  f"({row['wall_s']} s wall)", file=sys.stderr, flush=True)
    result["runs"] = rows
    result.update(summarize(rows, args.duration))
    print("\n| world | robots | method | t50 | t90 | t95 | t99 | reached 95 % | vs frontier |",
          file=sys.stderr)
    print("|---|---|---|---|---|---|---|---|---|", file=sys.stderr)
    for e in result["table"]:
        print(f"| {e['world']} | {e['robots']} | {e['method']} | {e['t50']} | {e['t90']} | "
              f"{e['t95']} | {e['t99']} | {e['reached_95']}/{e['runs']} | "
              f"{e.get('ratio_95', '-')} |", file=sys.stderr)
    print(f"time to 95 % over the frontier baseline's, mean of all cases: "
          f"{result['ratio_95_mean']}; target <= {TARGET_RATIO}: "
          f"{'met' if result['met'] else 'not met'} ({result['best']})", file=sys.stderr)
    if args.live:
        result["live"] = live_runs(4, 300.0, 0)
    if not args.no_results:
        write_explore_results(result, args, argv)
    print(json.dumps(result))
    return 0


def write_explore_results(result: dict, args: argparse.Namespace, argv: list[str] | None) -> None:
    """``docs/results/explore.json``: a row per world, team size and method (replacing that
    setting's row), and this run's targets."""
    from coverage_ros.bench.results import update_rows

    best = result["best"]
    targets = [{"figure": "coordinated exploration (best: "
                f"{best}): time to 95 % over the frontier baseline's, mean of this run's cases",
                "value": result["ratio_95_mean"].get(best) if best else None,
                "target": f"<= {TARGET_RATIO}", "met": result["met"]}]
    sensor = result.get("sensor_model")
    if sensor:
        targets.insert(0, {"figure": "inverse sensor model, one 360-beam scan on 5 cm cells "
                           f"[ms] (per-beam reference: {sensor['reference_ms']} ms)",
                           "value": sensor["ms"], "target": "<= 2 ms", "met": sensor["met"]})
    settings = (f"worlds {args.worlds}; {' and '.join(map(str, args.robots))} robots; seeds "
                f"{' '.join(map(str, args.seeds))}; at most {args.duration:g} s of sim time per "
                "run (a level never reached counts as that limit)")
    update_rows("explore", result["table"], ("world", "robots", "method"), argv,
                "scripts/bench_explore", extra={"targets": targets, "settings": settings})


if __name__ == "__main__":
    sys.exit(main())
