"""Geodesic teams and dead-end rooms (``scripts/bench_closets``): how far above the best known
configuration a team from the launcher's start cluster ends.

For every map and start seed, the team starts where ``coverage-team`` puts it
(:func:`~coverage_ros.core.world.placement.team_starts`: a compact seeded cluster) and runs the
``geodesic`` strategy offline, every robot's own update (``coverage-plan``'s decentralized
runner), until it converges. The best known H of a map is the least H of ``--restarts`` runs of
the plain strategy (no escape) from random starts over the free space, of ``--escape-restarts``
runs of the strategy as shipped (escape on) from random starts of their own, and of every case
run of the same map in the results file. Each case reports ``ratio = H_final / H_best``; the
target is ratio <= 1.05.

Maps: the shared map_server maps (tb3_sandbox, depot, warehouse), the shipped floor plans
``office`` and ``ward`` (dead-end rooms off a corridor), and ``hostel``
(:func:`~coverage_ros.bench.closet_maps.hostel`, drawn for the benchmark as a check on a plan
the escape was not tuned on), and any number of plans drawn at random from a seed,
``plan-<seed>`` (:func:`~coverage_ros.bench.closet_maps.drawn_plan`: rooms of random widths on
both sides of a corridor, some with a closet inside) and ``twin-<seed>``
(:func:`~coverage_ros.bench.closet_maps.twin_plan`: two corridors with rooms outside them and
back to back between them); :mod:`coverage_ros.bench.closet_maps` has them. Every map is
rasterized at ``--resolution`` (coarser cells where the map's own are finer: an occupied or
unknown fine cell makes its coarse cell so), which keeps a restart of the largest map within
seconds.

Writes ``docs/results/closets.json`` (``--json``): one row per label and map (``rows``), the
runs under their ``--label`` (e.g. before / after), each with its settings and provenance, and
the restarts per map (kept and reused by later labels with the same settings).

With ``--live`` the cases are the launcher's team instead, run in lock-step on the same
rasters and scored the same way (:mod:`coverage_ros.bench.closets_live`); the README's table
gets a column for them.

    scripts/bench_closets --label before [--maps ward,office,plan-7] [--seeds 3] [--restarts 8]
    scripts/bench_closets --label live --live [--duration S] [--maps ward] [--jobs 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from coverage_ros.bench.closet_maps import (
    MAPS,
    RESOLUTION,
    ROBOTS,
    TWIN,
    coarse_world,
    entry,
    floor_plan,
    known_map,
    score,
)
from coverage_ros.bench.closets_results import (
    README,
    RESULTS,
    best_and_ratios,
    table,
    update_readme,
    write,
)
from coverage_ros.bench.results import provenance
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.runner import OfflineConfig, run_offline
from coverage_ros.core.strategies import StrategyContext, strategy_choice
from coverage_ros.core.world import WorldSpec, load_world, parse_world
from coverage_ros.core.world.placement import largest_free_region, team_starts
from coverage_ros.errors import ConfigError
from coverage_ros.worlds import resolve_world_path

TOLERANCE = 0.02  # [m] converged when no robot moves more than this (coverage-plan's default)
MAX_ITERATIONS = 300  # coverage-plan's default
#: [s] the longest simulated time of a live run (--live): a relocation across a plan takes a
#: live robot 60-100 s and a team may make several (drawn plan 2, start seed 2: 1.200 of the
#: best known at 300 s, within 5 % from 410 s on)
LIVE_DURATION = 900.0
#: [s] ... on the warehouse (30 x 50 m), where crossings take longer still
LIVE_DURATIONS = {"warehouse": 1500.0}
#: [s] ... on the twin plans (20 x 18.5 m, 24 rooms off two corridors): a team makes 3-10
#: relocations of 80-130 s each (twin-0's start seeds: 8, 3 and 10, settled by 1095 s)
TWIN_LIVE_DURATION = 1800.0
#: [s] sim time a live run ends after once settled (coverage-team --until-settled): longer than
#: the pause between a team settling and its next relocation
LIVE_SETTLE = 60.0


def run_team(domain: CoverageDomain, world: WorldSpec, starts: np.ndarray, params: dict,
             max_iterations: int) -> dict:
    """The geodesic strategy with ``params``, every robot's own update, from ``starts``."""
    n = len(starts)
    choice = strategy_choice("geodesic", params, "strategy params")
    contexts = [StrategyContext(domain=domain, robot=world.robot_spec(i), robot_id=i,
                                convergence_tolerance=TOLERANCE, seed=i) for i in range(n)]
    t0 = time.perf_counter()
    done = run_offline(domain, choice, starts, contexts=contexts,
                       config=OfflineConfig(max_iterations=max_iterations))
    H, masses = score(domain, done.positions[-1])
    free = all(domain.is_free_point(p) for p in done.positions[-1])
    modes = [d.mode for d in done.decisions]
    return {"H": H, "H_start": score(domain, done.positions[0])[0],
            "iterations": int(done.iterations), "converged": bool(done.converged),
            "masses": np.round(masses, 4).tolist(), "all_free": bool(free),
            "relocations": int(sum(getattr(d.details, "relocations", 0)
                                   for d in done.decisions)),
            "final_modes": modes, "positions": np.round(done.positions[-1], 3).tolist(),
            "seconds": round(time.perf_counter() - t0, 2)}


def random_starts(world: WorldSpec, n: int, radius: float, rng: np.random.Generator
                  ) -> np.ndarray:
    """``(n, 2)`` [m] distinct free cell centres drawn uniformly from the largest free region."""
    grid = world.grid
    cells = np.argwhere(largest_free_region(grid, radius))
    pick = rng.choice(len(cells), size=n, replace=False)
    return grid.cell_centers(cells[pick])


def plain_params() -> dict:
    """The strategy's settings without the escape (where the strategy has one)."""
    from coverage_ros.core.strategies.geodesic import GeodesicParams

    names = {f.name for f in dataclasses.fields(GeodesicParams)}
    return {"escape": False} if "escape" in names else {}


def bench_map(name: str, args, stored: dict, say) -> dict:
    plan = floor_plan(name)
    base = parse_world(plan) if plan is not None else load_world(
        resolve_world_path(str(MAPS[name]), "--maps"))
    world = coarse_world(base, args.resolution)
    specs = [world.robot_spec(i) for i in range(args.robots)]
    radius = max(s.radius for s in specs)
    domain = world_domain(world, radius)
    say(f"{name}: {domain.shape[1]} x {domain.shape[0]} cells at {domain.resolution:g} m, "
        f"{args.robots} robots")
    settings = {"robots": args.robots, "resolution": domain.resolution,
                "max_iterations": args.max_iterations, "restart_seed": args.restart_seed}
    key = entry(name, args.robots)
    restarts = stored.get(key) if stored.get(key, {}).get("settings") == settings else None
    kept = [] if restarts is None else restarts.get("escape_H", [])
    escape_provenance = None if restarts is None else restarts.get("escape_provenance")
    if restarts is None or len(restarts["H"]) < args.restarts:
        rng = np.random.default_rng(args.restart_seed)
        Hs = []
        for r in range(args.restarts):
            starts = random_starts(world, args.robots, radius, rng)
            run = run_team(domain, world, starts, plain_params(), args.max_iterations)
            Hs.append(run["H"])
            say(f"  restart {r + 1}/{args.restarts}: H {run['H']:.4g} "
                f"({run['iterations']} iterations, {run['seconds']} s)")
        restarts = {"settings": settings, "H": Hs}
    else:
        say(f"  {len(restarts['H'])} restarts reused from the results file")
    escape = list(kept)
    if len(escape) < args.escape_restarts:
        escape_provenance = provenance()  # (of the latest ones run: the code they ran)
        # the strategy as shipped (escape on) from random starts of a stream of their own;
        # the ones on record are the stream's first (their starts drawn again, not run)
        rng = np.random.default_rng([args.restart_seed, 1])
        for r in range(args.escape_restarts):
            starts = random_starts(world, args.robots, radius, rng)
            if r < len(kept):
                continue
            run = run_team(domain, world, starts, {}, args.max_iterations)
            escape.append(run["H"])
            say(f"  restart with escape {r + 1}/{args.escape_restarts}: H {run['H']:.4g} "
                f"({run['iterations']} iterations, {run['relocations']} relocations, "
                f"{run['seconds']} s)")
    elif escape:
        say(f"  {len(escape)} restarts with escape reused from the results file")
    if escape:
        restarts = {**restarts, "escape_H": escape}
        if escape_provenance is not None:
            restarts["escape_provenance"] = escape_provenance
    cases = []
    for seed in range(args.seeds):
        starts = team_starts(world, specs, None, seed)
        run = run_team(domain, world, starts, args.params, args.max_iterations)
        run["seed"] = seed
        cases.append(run)
        say(f"  start seed {seed}: H {run['H_start']:.4g} -> {run['H']:.4g} in "
            f"{run['iterations']} iterations ({run['relocations']} relocations, "
            f"{run['seconds']} s)")
    return {"settings": settings, "restarts": restarts, "cases": cases}


def main(argv: list[str] | None = None) -> int:
    try:
        return _main(argv)
    except ConfigError as exc:  # a wrong option or results file: one line, no traceback
        print(f"bench_closets: error: {exc}", file=sys.stderr)
        return 2


def _main(argv: list[str] | None) -> int:
    ap = argparse.ArgumentParser(prog="bench_closets",
                                 description=__doc__.split("\n\n")[0].replace("\n", " "))
    ap.add_argument("--label", required=True, help="name of this run in the results file")
    ap.add_argument("--maps", default=",".join(MAPS),
                    help=f"some of {','.join(MAPS)} and drawn plans plan-<seed>, twin-<seed>")
    ap.add_argument("--seeds", type=int, default=3, help="start seeds per map (0, 1, ...)")
    ap.add_argument("--restarts", type=int, default=8, help="random restarts per map (N)")
    ap.add_argument("--escape-restarts", type=int, default=0, metavar="M",
                    help="random restarts per map of the strategy with its default escape "
                         "too (M; kept and reused like the plain ones)")
    ap.add_argument("--restart-seed", type=int, default=1000)
    ap.add_argument("--robots", type=int, default=ROBOTS,
                    help=f"team size (default {ROBOTS}); another size makes rows, restarts and "
                         f"a best known H of its own, under '<map>, <robots> robots'")
    ap.add_argument("--resolution", type=float, default=RESOLUTION, help="[m] benchmark raster")
    ap.add_argument("--max-iterations", type=int, default=MAX_ITERATIONS)
    ap.add_argument("--strategy-params", default="",
                    help="YAML mapping of the geodesic strategy's settings for the cases")
    ap.add_argument("--live", action="store_true",
                    help="run the launcher's team in lock-step instead of the offline cases "
                         "(coverage_ros.bench.closets_live)")
    per_map = ", ".join([*(f"{m} {s:g} s" for m, s in LIVE_DURATIONS.items()),
                         f"twin-<seed> {TWIN_LIVE_DURATION:g} s"])
    ap.add_argument("--duration", type=float, default=None,
                    help=f"[s] with --live: simulated time of each run (default "
                         f"{LIVE_DURATION:g} s; {per_map})")
    ap.add_argument("--until-settled", type=float, default=LIVE_SETTLE, metavar="S",
                    help=f"[s] with --live: end a run once settled for S s of sim time "
                         f"(coverage-team --until-settled; default {LIVE_SETTLE:g}; 0: run "
                         f"the whole --duration)")
    ap.add_argument("--jobs", type=int, default=1,
                    help="with --live: runs at once (start seeds of a map), each team in its "
                         "own ROS domain")
    ap.add_argument("--keep", type=Path, default=None, metavar="DIR",
                    help="with --live: keep each run's folder (world file, node logs, "
                         "summary) as DIR/<map>/seed-<k> instead of deleting it")
    ap.add_argument("--record", action="store_true",
                    help="with --keep: also record each run for the rerun viewer "
                         "(recording.rrd in its folder; lock-step: the same run)")
    ap.add_argument("--json", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    if (args.keep is not None or args.record) and not args.live:
        raise ConfigError.at("--keep" if args.keep is not None else "--record",
                             "applies to live runs only", expected="--live as well")
    if args.record and args.keep is None:
        raise ConfigError.at("--record", "needs a folder to keep the recordings in",
                             expected="--keep DIR as well")
    if args.escape_restarts < 0:
        raise ConfigError.at("--escape-restarts", "must be >= 0", args.escape_restarts)
    if args.escape_restarts and args.live:
        raise ConfigError.at("--escape-restarts", "applies to offline runs only",
                             expected="no --live")
    if args.robots < 1:
        raise ConfigError.at("--robots", "must be >= 1", args.robots)
    if args.jobs < 1:
        raise ConfigError.at("--jobs", "must be >= 1", args.jobs)
    if args.duration is not None and args.duration <= 0:
        raise ConfigError.at("--duration", "must be > 0", args.duration)
    if not args.until_settled >= 0:
        raise ConfigError.at("--until-settled", "must be >= 0 [s]", args.until_settled)
    from coverage_ros.core.world.yaml_io import yaml_mapping

    args.params = yaml_mapping(args.strategy_params, "--strategy-params")
    maps = [m for m in args.maps.split(",") if m]
    unknown = sorted(m for m in set(maps) if not known_map(m))
    if unknown:
        raise ConfigError.at("--maps", "unknown maps", unknown,
                             f"some of {sorted(MAPS)} or plan-<seed>, twin-<seed> (drawn plans)")

    def say(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    data = json.loads(args.json.read_text()) if args.json.exists() else {}
    runs = data.setdefault("runs", {})
    stored = data.setdefault("restarts", {})
    label = runs.setdefault(args.label, {"maps": {}})
    label.update(provenance=provenance(), strategy_params=args.params,
                 settings={"seeds": args.seeds, "restarts": args.restarts,
                          "escape_restarts": args.escape_restarts,
                           "robots": args.robots, "resolution": args.resolution,
                           "tolerance": TOLERANCE, "max_iterations": args.max_iterations})
    if args.live:
        from coverage_ros.bench.closets_live import bench_live, check_maps

        best_and_ratios(data)
        check_maps([entry(m, args.robots) for m in maps], data)
        label["settings"].update(live=True)  # (each map's own settings give its duration)
        label["settings"].pop("restarts")
        label["settings"].pop("escape_restarts")
        label["settings"].pop("duration", None)
        for name in maps:
            duration = args.duration or live_duration(name)
            result = bench_live(args, [name], data, say, duration)[name]
            label["maps"][entry(name, args.robots)] = {**result,
                                                       "provenance": label["provenance"]}
            write(data, args.json, args.label)
    for name in [] if args.live else maps:
        result = bench_map(name, args, stored, say)
        key = entry(name, args.robots)  # (a team of another size: an entry of its own)
        stored[key] = result["restarts"]
        # a label's maps may come from runs of different commits: each keeps its own
        label["maps"][key] = {"settings": result["settings"], "cases": result["cases"],
                              "provenance": label["provenance"]}
        write(data, args.json, args.label)
    print(table(data))
    say(f"wrote {args.json}")
    if args.json.resolve() == RESULTS.resolve() and update_readme(data, README):
        say(f"updated the table in {README}")
    return 0


def live_duration(name: str) -> float:
    """[s] the default sim time of a live run on map ``name``."""
    if TWIN.fullmatch(name) is not None:
        return TWIN_LIVE_DURATION
    return LIVE_DURATIONS.get(name, LIVE_DURATION)


if __name__ == "__main__":
    sys.exit(main())
