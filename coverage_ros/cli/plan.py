"""coverage-plan: run a coverage strategy offline on a map and report where the robots end.

Every robot's decentralized update is run centrally, iteration after iteration, until the
team converges (see :mod:`coverage_ros.core.offline.runner`); with ``--solver lloyd`` or
``accelerated`` (strategies lloyd and geodesic) the whole team's step is computed at once
instead, plain Lloyd or Lloyd then L-BFGS on H once plain Lloyd's tail settles, then
relocations (:mod:`coverage_ros.core.offline.lloyd_solvers`). Writes a
JSON summary, a PNG picture and optionally a rerun recording; prints progress to stderr.

    coverage-plan --map ../shared/maps/tb3_sandbox.yaml --robots 6 --json plan.json --png plan.png
"""

from __future__ import annotations

import os

# A plan is computed on one thread: OpenBLAS's idle workers would only start up and spin beside
# it (set before numpy loads; a user's own setting wins).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from coverage_ros.cli.arguments import attach_values
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.lloyd_solvers import HOPS
from coverage_ros.core.offline.lloyd_team import (
    SOLVERS,
    EuclideanTeam,
    GeodesicTeam,
    TeamStep,
    solve_lloyd,
)
from coverage_ros.core.world import WorldSpec, load_world
from coverage_ros.core.world.placement import check_free_area, team_starts
from coverage_ros.core.world.robot import TB3_RADIUS
from coverage_ros.core.world.yaml_io import yaml_mapping
from coverage_ros.errors import ConfigError, CoverageError
from coverage_ros.worlds import resolve_world_path

#: [s] sim time of an exploration at most, unless --duration
EXPLORE_DURATION = 900.0
#: picture formats --png writes (by the file's extension)
IMAGE_SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".bmp", ".gif", ".tif", ".tiff", ".webp"})


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="coverage-plan", description=__doc__.split("\n")[0])
    ap.add_argument("--map", required=True,
                    help="map_server YAML, package world YAML, or a shipped world name")
    ap.add_argument("--robots", type=int, required=True, help="team size")
    ap.add_argument("--starts", help="start positions 'x,y;x,y;...' [m] (default: the world's "
                    "start poses if it lists one per robot, else a compact seeded cluster, so "
                    "the robots must spread)")
    ap.add_argument("--strategy", default="geodesic",
                    help="coverage strategy by name (an unknown name lists them); exploring: "
                    "geodesic or frontier")
    ap.add_argument("--strategy-params", default="",
                    help="YAML mapping of strategy parameters, e.g. '{method: paper}'")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--robot-radius", type=float, default=None,
                    help=f"[m] robot radius (default: the world's, TurtleBot3 {TB3_RADIUS})")
    ap.add_argument("--max-iterations", type=int, default=300)
    ap.add_argument("--tolerance", type=float, default=0.02,
                    help="[m] converged when no robot moves more than this")
    ap.add_argument("--solver", default="decentralized",
                    choices=("decentralized",) + SOLVERS,
                    help="with --strategy lloyd or geodesic: 'lloyd' / 'accelerated' run the "
                    "whole team's step at once (plain Lloyd / Lloyd, then L-BFGS on H once "
                    "Lloyd's tail settles, then relocations: --hops) instead of every "
                    "robot's own update")
    ap.add_argument("--hops", type=int, default=None,
                    help=f"with --solver accelerated: relocations tried after the descent, at "
                    f"most (default {HOPS}; 0: the descent alone, fewer steps, an end as "
                    f"likely above plain Lloyd's as below)")
    ap.add_argument("--connectivity", type=int, default=8, choices=(8, 16))
    ap.add_argument("--explore", action="store_true",
                    help="the robots start with no map and explore it (simulated lidar)")
    ap.add_argument("--duration", type=float, default=None,
                    help=f"[s] with --explore: sim time at most (default {EXPLORE_DURATION:g})")
    ap.add_argument("--until-explored", type=float, default=None, metavar="F",
                    help="with --explore: stop once this share of the free area is explored")
    ap.add_argument("--json", type=Path, help="write the JSON summary here")
    ap.add_argument("--png", type=Path, help="write a picture here")
    ap.add_argument("--record", type=Path, help="write a rerun recording (.rrd) here")
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    return ap


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse output paths that cannot be written before anything runs: a directory given
    for a file, a parent that is a file, a picture without a known image extension; make the
    missing parent directories."""
    for option, out in (("--json", args.json), ("--png", args.png), ("--record", args.record)):
        if out is None:
            continue
        if out.is_dir():
            raise ConfigError.at(option, "is a directory", str(out), "a file path")
        if option == "--png" and out.suffix.lower() not in IMAGE_SUFFIXES:
            raise ConfigError.at(option, "needs an image file extension", str(out),
                                 f"one of {sorted(IMAGE_SUFFIXES)}")
        parent = next((p for p in (out.parent, *out.parent.parents) if p.exists()), None)
        if parent is not None and not parent.is_dir():
            raise ConfigError.at(option, f"{parent} is a file, not a directory", str(out))
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError.at(option, f"cannot make its directory ({exc.strerror})",
                                 str(out)) from None


class Run(NamedTuple):
    """What a run left: the team's positions, start first (T + 1, n, 2) [m], and its steps."""

    positions: np.ndarray
    iterations: int
    converged: bool
    update_seconds: list[float]  # one robot's update, or one team step
    relocations: int = 0  # the accelerated team solver's relocations kept


def run(args: argparse.Namespace) -> dict:
    from coverage_ros.core.metrics import mass_deviation

    t0 = time.perf_counter()
    say = (lambda *_: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    if args.robots < 1:
        raise ConfigError.at("--robots", "must be >= 1", args.robots)
    if not (math.isfinite(args.tolerance) and args.tolerance > 0):
        raise ConfigError.at("--tolerance", "must be a finite number > 0", args.tolerance)
    if args.max_iterations < 1:
        raise ConfigError.at("--max-iterations", "must be >= 1", args.max_iterations)
    if args.hops is not None and args.solver != "accelerated":
        raise ConfigError.at("--hops", "needs --solver accelerated", args.hops)
    if args.hops is not None and args.hops < 0:
        raise ConfigError.at("--hops", "must be >= 0", args.hops)
    if args.duration is not None and not args.explore:
        raise ConfigError.at("--duration", "needs --explore (a plan without it runs until it "
                             "converges or --max-iterations)", args.duration)
    if args.record is not None and args.explore:
        raise ConfigError.at("--record", "not with --explore (record a live exploration with "
                             "coverage-team --explore --record)", str(args.record))
    if args.starts is not None and not args.starts.strip():
        raise ConfigError.at("--starts", "is empty", args.starts,
                             "'x,y;x,y;...' [m], one per robot (or no --starts: a cluster)")
    check_outputs(args)
    if args.explore and args.duration is None:
        args.duration = EXPLORE_DURATION
    path = resolve_world_path(args.map, "--map")
    world = load_world(path)
    settings = yaml_mapping(args.strategy_params, "--strategy-params")
    if args.solver != "decentralized" and (args.strategy not in ("lloyd", "geodesic")
                                           or args.explore):
        raise ConfigError.at("--solver", "needs --strategy lloyd or geodesic (and no --explore)",
                             args.solver, "decentralized")
    choice = None
    if args.solver == "decentralized" or args.strategy != "lloyd" or settings:
        # the registry imports every strategy (and scipy): not for the Euclidean team's
        # solver, with nothing to validate
        from coverage_ros.core.strategies import strategy_choice

        choice = strategy_choice(args.strategy, settings, "--strategy-params",
                                 explore=args.explore)
    if args.until_explored is not None and not (args.explore and 0 < args.until_explored <= 1):
        raise ConfigError.at("--until-explored", "needs --explore and a fraction in (0, 1]",
                             args.until_explored)
    specs = [world.robot_spec(i) for i in range(args.robots)]
    if args.robot_radius is not None:
        specs = [s.with_overrides({"radius": args.robot_radius}, "--robot-radius")
                 for s in specs]
    radius = max(s.radius for s in specs)
    check_free_area(world, args.robots, radius)
    starts = team_starts(world, specs, args.starts, args.seed)
    if args.explore:
        assert choice is not None  # (exploring plans are decentralized)
        from coverage_ros.cli.plan_explore import plan_exploration  # its simulator: only here

        summary = plan_exploration(args, world, path, choice, specs, starts, say)
        if args.json:
            args.json.write_text(json.dumps(summary, indent=2))
            say(f"  wrote {args.json}")
        return summary
    domain = world_domain(world, radius, connectivity=args.connectivity)
    weights = [s.power_weight for s in specs]
    say(f"coverage-plan: {args.strategy}, {args.robots} robots on {path} "
        f"({domain.shape[1]} x {domain.shape[0]} cells at {domain.resolution:g} m)")

    def progress(it: int, cost: float) -> None:
        if it == 1 or it % 10 == 0:
            say(f"  iteration {it:4d}: sum of cell costs {cost:.4g}")

    if args.solver == "decentralized":
        from coverage_ros.core.offline.runner import OfflineConfig, run_offline
        from coverage_ros.core.strategies import StrategyContext

        contexts = [StrategyContext(domain=domain, robot=specs[i], robot_id=i,
                                    convergence_tolerance=args.tolerance, seed=args.seed + i)
                    for i in range(args.robots)]
        assert choice is not None
        done = run_offline(domain, choice, starts, contexts=contexts,
                           config=OfflineConfig(max_iterations=args.max_iterations),
                           progress=progress)
        result = Run(done.positions, done.iterations, done.converged, done.update_seconds)
        first = last = None
    else:
        team = EuclideanTeam(domain) if args.strategy == "lloyd" or choice is None else \
            GeodesicTeam(domain, choice.params.method)
        if choice is not None and getattr(choice.params, "escape", False):  # (geodesic's)
            say("  note: the team solvers run Lloyd (the accelerated one with its relocations); "
                "the closet escape runs in the robots' own updates: --solver decentralized")
        result, first, last = _solve_team(args, team, weights, starts, progress)
    final, H0 = _score(domain, result.positions[-1], weights, last), \
        _score(domain, result.positions[0], weights, first).cost
    # sorted [ms]; np.median and np.percentile would import numpy.ma (15 ms) for two numbers
    ms = np.sort(np.array(result.update_seconds) * 1e3)
    summary = {
        "map": str(path), "strategy": args.strategy, "solver": args.solver,
        "robots": args.robots,
        "start_positions": result.positions[0].round(4).tolist(),
        "positions": result.positions[-1].round(4).tolist(),
        "H": float(final.cost), "H_start": float(H0),
        "iterations": int(result.iterations), "converged": bool(result.converged),
        **({"relocations": result.relocations} if args.solver == "accelerated" else {}),
        "update_ms": {"median": _quantile(ms, 0.5), "p90": _quantile(ms, 0.9),
                      "max": float(ms[-1])},
        "grid": {"width": domain.shape[1], "height": domain.shape[0],
                 "resolution": domain.resolution},
        "masses": final.masses.round(6).tolist(),
        "mass_deviation_I": mass_deviation(final.masses),
        "wall_time_s": round(time.perf_counter() - t0, 3),
    }
    say(f"  {'converged' if result.converged else 'stopped'} after {result.iterations} "
        f"iterations: H {H0:.4g} -> {final.cost:.4g}; "
        f"{'one update' if args.solver == 'decentralized' else 'one team step'}: median "
        f"{summary['update_ms']['median']:.1f} ms")
    if args.json:
        args.json.write_text(json.dumps(summary, indent=2))
        say(f"  wrote {args.json}")
    if args.png:
        from coverage_ros.viz.png import density_underlay, render_plan

        render_plan(world.grid, final.labels, result.positions, args.png,
                    title=f"{args.strategy}"
                    f"{'' if args.solver == 'decentralized' else f' ({args.solver} solver)'}: "
                    f"{args.robots} robots, H = {final.cost:.4g}",
                    underlay=density_underlay(domain.density)
                    if domain.density.shape == world.grid.shape else None)
        say(f"  wrote {args.png}")
    if args.record:
        record(args.record, domain, world, result, args.robots, radius)
        say(f"  wrote {args.record} (open with: rerun {args.record})")
    return summary


def _quantile(ordered: np.ndarray, q: float) -> float:
    """np.quantile's default (linear) of ascending ``ordered``."""
    at = q * (len(ordered) - 1)
    lo = int(at)
    hi = min(lo + 1, len(ordered) - 1)
    return float(ordered[lo] + (at - lo) * (ordered[hi] - ordered[lo]))


def _score(domain: CoverageDomain, positions: np.ndarray, weights: list[float],
           step: TeamStep | None):
    """The team's geodesic power Voronoi tessellation at ``positions`` (H, masses, labels), the
    score of every strategy: a Euclidean team step where it is that tessellation (the team's
    own, :attr:`EuclideanTeam.is_geodesic`), else the quickest exact search."""
    if step is not None and step.geodesic:
        return step
    from coverage_ros.core.geodesic.tessellation import Generator, fast_tessellate

    return fast_tessellate(domain, [Generator(p, w) for p, w in
                                    zip(positions, weights, strict=True)])


def _solve_team(args, team: EuclideanTeam | GeodesicTeam, weights: list[float],
                starts: np.ndarray, progress) -> tuple[Run, TeamStep, TeamStep]:
    """The whole team's (generalized) Lloyd step at once (``--solver``); update times are
    whole team steps. Also the first and last team steps."""
    t0 = time.perf_counter()
    sol = solve_lloyd(team, starts[:, :2], np.array(weights), args.solver,
                      tolerance=args.tolerance, max_steps=args.max_iterations,
                      hops=HOPS if args.hops is None else args.hops, progress=progress)
    step = (time.perf_counter() - t0) / sol.steps
    return Run(sol.positions, sol.steps, sol.converged, [step] * sol.steps,
               len(sol.hops)), sol.first, sol.last


def record(path: Path, domain: CoverageDomain, world: WorldSpec, result, n: int,
           radius: float) -> None:
    from coverage_ros.core.geodesic.tessellation import Generator, tessellate
    from coverage_ros.viz.recording import CoverageRecorder

    rec = CoverageRecorder()
    rec.log_map(world.grid, domain.density)
    ids = list(range(n))
    rec.name_series(ids)
    for t, P in enumerate(result.positions):
        rec.set_time(float(t))
        tess = tessellate(domain, [Generator(p) for p in P])
        rec.log_cells(tess.labels, ids)
        rec.log_robots(ids, P, radius)
        rec.log_metrics(tess.cost, {i: float(m) for i, m in enumerate(tess.masses)})
        for i in ids:
            rec.log_path("trajectories", i, result.positions[:t + 1, i])
    rec.save(path)
    rec.flush()


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(attach_values(sys.argv[1:] if argv is None else argv))
    try:
        run(args)
    except CoverageError as exc:
        print(f"coverage-plan: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
