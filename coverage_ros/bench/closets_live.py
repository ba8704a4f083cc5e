"""Live geodesic teams and dead-end rooms (``scripts/bench_closets --live``): the real
launcher's team, run in lock-step, against the best known configuration of
``scripts/bench_closets``.

For every map and start seed, ``coverage-team --strategy geodesic --lockstep`` runs the world
node and one robot process per robot until the team has settled (``--until-settled``, 60 s by
default) or for at most ``--duration`` seconds of simulated time (by default per map:
:func:`~coverage_ros.bench.closets.live_duration`) from the
launcher's start cluster (the same cluster the offline cases start from). The world is the
benchmark's raster of the map (:func:`~coverage_ros.bench.closet_maps.coarse_world`), written as a
world file (floor plans) or a map_server map (the shared maps) that the launcher loads as a user
would. The robots' final positions are scored as the offline cases are
(:func:`~coverage_ros.bench.closet_maps.score`), so ``ratio = H_final / H_best`` compares with the
offline rows and the best known H of ``docs/results/closets.json``; the target is again
ratio <= 1.05. The run's own H series gives the sim time from which H stayed within 5 % of the
best known.

The cases go into the results file under ``--label`` (default ``live``) with their own
settings (the duration); a live end lower than every restart's is the best known H (a
configuration's H does not depend on how it was found). A run's folder (world
file, node logs, summary) is deleted once its map is done unless ``--keep DIR`` keeps it as
``DIR/<map>/seed-<k>``, with ``--record`` also a recording to watch in the rerun viewer; the
folder of a run that fails is kept either way (the error names it: the world's and the robots'
logs say why).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import yaml

from coverage_ros.bench.closet_maps import (
    MAPS,
    TARGET,
    coarse_world,
    entry,
    floor_plan,
    score,
)
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.world import WorldSpec, load_world, parse_world
from coverage_ros.core.world.map_server import write_map_yaml
from coverage_ros.errors import ConfigError
from coverage_ros.worlds import resolve_world_path

TEAM = [sys.executable, "-m", "coverage_ros.cli.team"]
#: Slower than this share of real time, a live run is stuck: its wall-clock limit is its
#: duration over this (a run that overstays is a failure, not a result). Lock-step teams of 8
#: on the warehouse run at 0.2-0.3 of real time three at once on two cores.
MIN_RTF = 0.05


def world_file(name: str, resolution: float, folder: Path) -> tuple[Path, WorldSpec]:
    """Map ``name`` at the benchmark's raster as a file the launcher loads, and its spec as
    the offline cases see it."""
    folder.mkdir(parents=True, exist_ok=True)
    drawn = floor_plan(name)
    if drawn is not None:
        plan = drawn
    else:
        path = Path(resolve_world_path(str(MAPS[name]), "--maps"))
        plan = yaml.safe_load(path.read_text())
        if "image" in plan:  # a map_server map: its cells in blocks
            world = coarse_world(load_world(str(path)), resolution)
            assert world.base_map is not None
            out = write_map_yaml(world.base_map, folder / f"{name}.yaml")
            return out, world
    plan = {**plan, "resolution": max(float(plan.get("resolution", resolution)), resolution)}
    out = folder / f"{name}.yaml"
    out.write_text(yaml.safe_dump(plan, sort_keys=False))
    return out, parse_world(plan)


def run_case(name: str, seed: int, args, folder: Path, duration: float) -> dict:
    """One live run of map ``name`` from start seed ``seed`` for ``duration`` [s] of sim
    time; its case row."""
    path, world = world_file(name, args.resolution, folder)
    out = folder / f"{name}-{seed}"
    cmd = ["--world", str(path), "--robots", str(args.robots), "--strategy", "geodesic",
           "--lockstep", "--duration", f"{duration:g}", "--seed", str(seed),
           "--out", str(out), "--quiet"]
    if args.until_settled > 0:
        cmd += ["--until-settled", f"{args.until_settled:g}"]
    if args.params:
        cmd += ["--strategy-params", json.dumps(args.params)]
    if getattr(args, "record", False):
        cmd += ["--record"]
    t0 = time.perf_counter()
    proc = subprocess.run(TEAM + cmd, capture_output=True, text=True, timeout=duration / MIN_RTF)
    if proc.returncode != 0:
        kept = folder if getattr(args, "keep", None) is not None else keep_failed(folder)
        raise RuntimeError(f"coverage-team {' '.join(cmd)} failed ({proc.returncode}); its "
                           f"world file and logs are in {kept}:\n{proc.stderr[-2000:]}")
    summary = json.loads((out / "summary.json").read_text())
    specs = [world.robot_spec(i) for i in range(args.robots)]
    domain = world_domain(world, max(s.radius for s in specs))
    final = np.array([r["final"][:2] for r in summary["robots"]], dtype=np.float64)
    start = np.array([r["start"][:2] for r in summary["robots"]], dtype=np.float64)
    H, masses = score(domain, final)
    return {"seed": seed, "H": H, "H_start": score(domain, start)[0],
            "sim_time": summary["sim_time"], "settled_at": summary.get("settled_at"),
            "rtf": summary["rtf"],
            "seconds": round(time.perf_counter() - t0, 1),
            "H_series": summary["metrics"].get("H_series", []),
            "collisions": int(sum(r["collisions"] for r in summary["robots"])),
            "masses": np.round(masses, 4).tolist(), "positions": np.round(final, 3).tolist(),
            "all_free": bool(all(domain.is_free_point(p) for p in final))}


def keep_failed(folder: Path) -> Path:
    """A copy of a failed run's ``folder`` outside the benchmark's temporary folder, which is
    deleted when the benchmark ends."""
    kept = Path(tempfile.mkdtemp(prefix=f"bench-closets-failed-{folder.parent.name}-"))
    shutil.copytree(folder, kept / folder.name)
    return kept / folder.name


def within_at(series: list, H_best: float, share: float = TARGET - 1.0) -> float | None:
    """First sim time [s] from which the run's H series stayed within ``share`` of
    ``H_best`` (None: it did not end there)."""
    t_in = None
    for t, h in reversed(series):
        if not h <= (1.0 + share) * H_best:
            break
        t_in = t
    return t_in


def bench_live(args, maps: list[str], data: dict, say, duration: float) -> dict[str, dict]:
    """Every map and start seed live for ``duration`` [s] of sim time, ``args.jobs`` runs at
    once (lock-step: a run's result does not depend on what else the machine does); per map
    its settings and cases."""
    best = data.get("best", {})
    results = {}
    keep = getattr(args, "keep", None)
    with tempfile.TemporaryDirectory(prefix="bench-closets-live-") as tmp:
        for name in maps:
            root = Path(tmp) / name if keep is None else Path(keep) / name
            settings = {"robots": args.robots, "resolution": args.resolution,
                        "live": True, "duration": duration}
            if args.until_settled > 0:
                settings["until_settled"] = args.until_settled
            cases = []
            with ThreadPoolExecutor(max_workers=args.jobs) as jobs:
                # (each team in its own ROS domain, its world file in its own folder)
                runs = [jobs.submit(run_case, name, seed, args, root / f"seed-{seed}",
                                    duration) for seed in range(args.seeds)]
                done = [run.result() for run in runs]
            for seed, case in enumerate(done):
                H_best = best.get(entry(name, args.robots), {}).get("H")
                series = case.pop("H_series")
                case["within_at"] = None if H_best is None else within_at(series, H_best)
                cases.append(case)
                ratio = "-" if H_best is None else f"{case['H'] / H_best:.3f}"
                say(f"  {name} start seed {seed}: H {case['H_start']:.4g} -> {case['H']:.4g} "
                    f"(x{ratio} the best known) after {case['sim_time']:g} s of sim time"
                    f"{'' if case['settled_at'] is None else ', settled'} "
                    f"(rtf {case['rtf']:.2f}, {case['seconds']:g} s, within 5 % from "
                    f"{case['within_at']} s)")
            results[name] = {"settings": settings, "cases": cases}
    return results


def check_maps(maps: list[str], data: dict) -> None:
    """Refuse a map without a best known H before anything starts."""
    missing = [m for m in maps if m not in data.get("best", {})]
    if missing:
        raise ConfigError.at("--maps", "no best known H in the results file (run "
                             "scripts/bench_closets for them first)", missing)
