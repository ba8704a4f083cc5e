"""Geodesic teams and dead-end rooms (``scripts/bench_closets``): how far above the best known
configuration a team from the launcher's start cluster ends.

For every map and start seed, the team starts where ``coverage-team`` puts it
(:func:`~coverage_ros.core.world.placement.team_starts`: a compact seeded cluster) and runs the
``geodesic`` strategy offline, every robot's own update (``coverage-plan``'s decentralized
runner), until it converges. The best known H of a map is the least H of ``--restarts`` runs of
the plain strategy (no escape) from random starts over the free space, and of every case run
of the same map in the results file. Each case reports ``ratio = H_final / H_best``; the
target is ratio <= 1.05.

Maps: the shared map_server maps (tb3_sandbox, depot, warehouse) and the shipped floor plans
``office`` and ``ward`` (dead-end rooms off a corridor). Every map is rasterized at
``--resolution`` (coarser cells where the map's own are finer: an occupied or unknown fine cell
makes its coarse cell so), which keeps a restart of the largest map within seconds.

Writes ``docs/results/closets.json`` (``--json``): one row per label and map (``rows``), the
runs under their ``--label`` (e.g. before / after), each with its settings and provenance, and
the restarts per map (kept and reused by later labels with the same settings).

    scripts/bench_closets --label before [--maps ward,office] [--seeds 3] [--restarts 8]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from coverage_ros.bench.environment import REPO, SHARED_MAPS
from coverage_ros.bench.results import provenance
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tessellation import Generator, fast_tessellate
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.runner import OfflineConfig, run_offline
from coverage_ros.core.strategies import StrategyContext, strategy_choice
from coverage_ros.core.world import WorldSpec, load_world
from coverage_ros.core.world.grid import FREE, OCCUPIED, UNKNOWN, GridMap
from coverage_ros.core.world.placement import largest_free_region, team_starts
from coverage_ros.errors import ConfigError
from coverage_ros.worlds import resolve_world_path

MAPS = {"tb3_sandbox": SHARED_MAPS / "tb3_sandbox.yaml", "depot": SHARED_MAPS / "depot.yaml",
        "warehouse": SHARED_MAPS / "warehouse.yaml", "office": "office", "ward": "ward"}
ROBOTS = 8
RESOLUTION = 0.1  # [m] benchmark raster: a restart on warehouse (30 x 50 m) in seconds
TOLERANCE = 0.02  # [m] converged when no robot moves more than this (coverage-plan's default)
MAX_ITERATIONS = 300  # coverage-plan's default
TARGET = 1.05  # H_final / H_best at most
RESULTS = REPO / "docs" / "results" / "closets.json"


def coarse_world(world: WorldSpec, resolution: float) -> WorldSpec:
    """``world`` rasterized at ``resolution`` [m] when its own cells are finer: a floor plan
    (bounds and obstacles) anew, a map_server map by blocks of whole cells (occupied if any
    fine cell is, else unknown if any is, else free)."""
    if world.resolution >= resolution - 1e-12:
        return world
    if world.base_map is None:
        return dataclasses.replace(world, resolution=resolution)
    base = world.base_map
    k = max(1, int(round(resolution / base.resolution)))
    h, w = (base.shape[0] // k) * k, (base.shape[1] // k) * k
    blocks = base.occupancy[:h, :w].reshape(h // k, k, w // k, k)
    occupied = (blocks >= OCCUPIED // 2).any(axis=(1, 3))
    unknown = (blocks < 0).any(axis=(1, 3))
    occ = np.where(occupied, OCCUPIED, np.where(unknown, UNKNOWN, FREE)).astype(np.int8)
    grid = GridMap(occ, base.resolution * k, base.origin)
    return dataclasses.replace(world, resolution=grid.resolution, base_map=grid)


def score(domain: CoverageDomain, positions: np.ndarray) -> tuple[float, np.ndarray]:
    """H and the cell masses of the team at ``positions (n, 2)`` [m]."""
    tess = fast_tessellate(domain, [Generator(p) for p in positions])
    return tess.cost, tess.masses


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
    path = resolve_world_path(str(MAPS[name]), "--maps")
    world = coarse_world(load_world(path), args.resolution)
    specs = [world.robot_spec(i) for i in range(args.robots)]
    radius = max(s.radius for s in specs)
    domain = world_domain(world, radius)
    say(f"{name}: {domain.shape[1]} x {domain.shape[0]} cells at {domain.resolution:g} m, "
        f"{args.robots} robots")
    settings = {"robots": args.robots, "resolution": domain.resolution,
                "max_iterations": args.max_iterations, "restart_seed": args.restart_seed}
    restarts = stored.get(name) if stored.get(name, {}).get("settings") == settings else None
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
    ap = argparse.ArgumentParser(prog="bench_closets", description=__doc__.split("\n")[0])
    ap.add_argument("--label", required=True, help="name of this run in the results file")
    ap.add_argument("--maps", default=",".join(MAPS), help=f"some of {','.join(MAPS)}")
    ap.add_argument("--seeds", type=int, default=3, help="start seeds per map (0, 1, ...)")
    ap.add_argument("--restarts", type=int, default=8, help="random restarts per map (N)")
    ap.add_argument("--restart-seed", type=int, default=1000)
    ap.add_argument("--robots", type=int, default=ROBOTS)
    ap.add_argument("--resolution", type=float, default=RESOLUTION, help="[m] benchmark raster")
    ap.add_argument("--max-iterations", type=int, default=MAX_ITERATIONS)
    ap.add_argument("--strategy-params", default="",
                    help="YAML mapping of the geodesic strategy's settings for the cases")
    ap.add_argument("--json", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    from coverage_ros.core.world.yaml_io import yaml_mapping

    args.params = yaml_mapping(args.strategy_params, "--strategy-params")
    maps = [m for m in args.maps.split(",") if m]
    unknown = sorted(set(maps) - set(MAPS))
    if unknown:
        raise ConfigError.at("--maps", "unknown maps", unknown, f"some of {sorted(MAPS)}")

    def say(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    data = json.loads(args.json.read_text()) if args.json.exists() else {}
    runs = data.setdefault("runs", {})
    stored = data.setdefault("restarts", {})
    label = runs.setdefault(args.label, {"maps": {}})
    label.update(provenance=provenance(), strategy_params=args.params,
                 settings={"seeds": args.seeds, "restarts": args.restarts,
                           "robots": args.robots, "resolution": args.resolution,
                           "tolerance": TOLERANCE, "max_iterations": args.max_iterations})
    for name in maps:
        result = bench_map(name, args, stored, say)
        stored[name] = result["restarts"]
        label["maps"][name] = {"settings": result["settings"], "cases": result["cases"]}
        write(data, args.json, args.label)
    print(table(data))
    say(f"wrote {args.json}")
    return 0


def write(data: dict, path: Path, label: str) -> None:
    """The results file: the provenance of run ``label`` on top, one row per label and map
    (the docs' table), then the restarts and every case."""
    _best_and_ratios(data)
    top = {**data["runs"][label]["provenance"],
           "settings": data["runs"][label]["settings"],
           "targets": [{"figure": "H_final / H_best, every start seed of a map",
                        "target": f"<= {TARGET:g}"}],
           "rows": rows(data)}
    out = {**top, **{k: v for k, v in data.items() if k not in top}}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1))


def rows(data: dict) -> list[dict]:
    """One row per label and map: N, the best known H, each start seed's ratio."""
    out = []
    for label, run in data["runs"].items():
        for name, m in run["maps"].items():
            best = data["best"].get(name, {})
            out.append({"label": label, "map": name, "restarts": best.get("restarts"),
                        "H_best": best.get("H"),
                        "ratios": [round(c["ratio"], 4) for c in m["cases"]],
                        "relocations": [c.get("relocations", 0) for c in m["cases"]],
                        "worst_ratio": m["worst_ratio"], "met": m["met"],
                        "run": {"commit": run["provenance"].get("commit"),
                                "date": run["provenance"].get("date")}})
    return out


def _best_and_ratios(data: dict) -> None:
    """Best known H per map (restarts and every case of every label with the map's settings)
    and every case's ratio to it."""
    best: dict[str, float] = {}
    for name, r in data["restarts"].items():
        best[name] = min(r["H"])
    for run in data["runs"].values():
        for name, m in run["maps"].items():
            if m["settings"] == data["restarts"].get(name, {}).get("settings"):
                best[name] = min([best.get(name, math.inf)] + [c["H"] for c in m["cases"]])
    data["best"] = {name: {"H": h, "restarts": len(data["restarts"][name]["H"])}
                    for name, h in best.items()}
    for run in data["runs"].values():
        for name, m in run["maps"].items():
            for c in m["cases"]:
                c["ratio"] = c["H"] / best[name] if name in best else None
            ratios = [c["ratio"] for c in m["cases"] if c.get("ratio") is not None]
            m["worst_ratio"] = max(ratios) if ratios else None
            m["met"] = bool(ratios) and max(ratios) <= TARGET


def table(data: dict) -> str:
    """Every label's ratio per map and seed, with the best known H and N."""
    rows = [f"{'label':10s} {'map':12s} {'N':>3s} {'H_best':>10s}  ratio per start seed"
            f"{'':6s} worst  met (<= {TARGET:g})"]
    for label, run in data["runs"].items():
        for name, m in run["maps"].items():
            best = data["best"].get(name, {})
            ratios = " ".join(f"{c['ratio']:.3f}" for c in m["cases"])
            rows.append(f"{label:10s} {name:12s} {best.get('restarts', 0):3d} "
                        f"{best.get('H', math.nan):10.4g}  {ratios:26s} "
                        f"{m['worst_ratio']:.3f}  {'met' if m['met'] else 'not met'}")
    return "\n".join(rows)


if __name__ == "__main__":
    sys.exit(main())
