"""Benchmark of one robot's decentralized geodesic update (``scripts/bench_core``).

Scenario (Bhattacharya et al. 2014, Fig. 13 style): an n x n grid at 5 cm with an L-shaped
obstacle, 9 robots on a jittered 3 x 3 lattice; the centre robot updates its cell and control with
its 8 neighbours while all robots drift by about a centimetre per update, as they do between
control periods. Timed, interleaved in one process so machine-speed drift affects all alike:

* ``update_ms`` - the fast update in ``paper`` mode (the pseudo-code's sources and first-edge
  tangents), with its per-robot search cache;
* ``visibility_ms`` - the same in the default ``visibility`` mode;
* ``reference_ms`` - the straightforward heapq implementation of the pseudo-code
  (:func:`coverage_ros.core.geodesic.reference.paper_cell`), on the same inputs.

A second table shows how the update time follows the robot's own cell area: k x k robots on
n x n grids; equal n/k means equal cell area. First of all, the offline team step
(:mod:`coverage_ros.bench.team_step`): lloyd and geodesic per step, plain against accelerated
Lloyd, and the geodesic step at scale and among obstacles
(:mod:`coverage_ros.bench.geodesic_scale`: 32 robots on 1024 x 1024 cells, 8 on three maps,
8 on random 400 x 400 scenarios);
before that, a robot's cold update in the largest cell of 16 robots on depot
(:mod:`coverage_ros.bench.cold_update`).

Progress goes to stderr; the last stdout line is JSON. A whole run (not ``--cold-only`` or
``--team-step-only``) also writes ``docs/results/core.json``: the figures and the benchmark's
targets, each with whether it is met.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import numpy as np

from coverage_ros.core.geodesic.cell import SearchCache, geodesic_cell
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.reference import adjacency, paper_cell
from coverage_ros.core.geodesic.tessellation import Generator
from coverage_ros.core.world.grid import OCCUPIED, GridMap

RESOLUTION = 0.05  # [m] per cell, as the shipped maps
DRIFT = 0.01  # [m] std of each robot's motion between two updates


def l_shaped_grid(n: int) -> GridMap:
    """n x n cells with an L-shaped obstacle through the middle of the map."""
    occ = np.zeros((n, n), dtype=np.int8)
    a, b, t = int(0.30 * n), int(0.72 * n), max(2, int(0.05 * n))
    occ[a:b, int(0.62 * n):int(0.62 * n) + t] = OCCUPIED  # vertical bar
    occ[a:a + t, int(0.36 * n):int(0.62 * n) + t] = OCCUPIED  # horizontal bar
    return GridMap(occ, RESOLUTION, (0.0, 0.0, 0.0))


def lattice(domain: CoverageDomain, k: int, rng: np.random.Generator) -> np.ndarray:
    """k x k robots on a jittered lattice, moved off obstacles."""
    n = domain.shape[0]
    side = n * RESOLUTION
    pts = []
    for j in range(k):
        for i in range(k):
            p = np.array([(i + 0.5) * side / k, (j + 0.5) * side / k])
            p += rng.uniform(-0.08, 0.08, 2) * side / k
            pts.append(_free(domain, p))
    return np.array(pts)


def _free(domain: CoverageDomain, p: np.ndarray) -> np.ndarray:
    if domain.is_free_point(p):
        return p
    r, c = domain.geometry.world_to_cell(p)
    idx = domain.nearest_free_index
    return domain.geometry.cell_centers(np.array([[idx[0, r, c], idx[1, r, c]]]))[0]


def _drift(domain: CoverageDomain, P: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    Q = P + rng.normal(0.0, DRIFT, P.shape)
    return np.array([q if domain.is_free_point(q) else p for p, q in zip(P, Q, strict=True)])


def _say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def bench_grid(n: int, rounds: int, per_round: int, seed: int) -> dict:
    """Rounds of: ``per_round`` fast updates (each mode) while the robots drift, then the
    reference on the last inputs, then the fast updates again on those same inputs. The speedup
    is the median over rounds of reference time / median fast time of that round, which keeps
    the host's speed changes out of the ratio."""
    rng = np.random.default_rng(seed)
    domain = CoverageDomain.from_grid(l_shaped_grid(n), 0.0)
    adjacency(domain)  # the reference's adjacency lists: built once, like the fast tables
    P = lattice(domain, 3, rng)
    own = 4
    caches = {"paper": SearchCache(), "visibility": SearchCache()}
    times: dict[str, list[float]] = {"paper": [], "visibility": [], "reference": []}
    ratios, vis_ratios, cells, searched, expanded = [], [], [], [], []
    mismatches = 0
    t0 = time.perf_counter()
    geodesic_cell(domain, Generator(P[own]), [Generator(p) for p in np.delete(P, own, 0)],
                  cache=caches["paper"], method="paper")
    cold = time.perf_counter() - t0
    geodesic_cell(domain, Generator(P[own]), [Generator(p) for p in np.delete(P, own, 0)],
                  cache=caches["visibility"], method="visibility")

    def fast(mode: str, me: Generator, others: list[Generator]):
        t = time.perf_counter()
        res = geodesic_cell(domain, me, others, cache=caches[mode], method=mode)
        dt = time.perf_counter() - t
        times[mode].append(dt)
        return res, dt

    for r in range(rounds):
        round_times: dict[str, list[float]] = {"paper": [], "visibility": []}
        for _ in range(per_round):
            P = _drift(domain, P, rng)
            me, others = Generator(P[own]), [Generator(p) for p in np.delete(P, own, 0)]
            for mode in ("paper", "visibility"):
                res, dt = fast(mode, me, others)
                round_times[mode].append(dt)
                if mode == "paper":
                    cells.append(len(res.nodes))
                    searched.append(res.searched_nodes)
        t = time.perf_counter()
        ref = paper_cell(domain, me, others)
        ref_time = time.perf_counter() - t
        times["reference"].append(ref_time)
        expanded.append(ref.expanded)
        for mode in ("paper", "visibility"):
            for _ in range(per_round):
                res, dt = fast(mode, me, others)
                round_times[mode].append(dt)
                if mode == "paper" and not np.array_equal(np.sort(res.nodes), ref.nodes):
                    mismatches += 1
        ratios.append(ref_time / statistics.median(round_times["paper"]))
        vis_ratios.append(ref_time / statistics.median(round_times["visibility"]))
        _say(f"  n={n}: round {r + 1}/{rounds}: reference {ref_time * 1e3:.0f} ms, "
             f"fast {statistics.median(round_times['paper']) * 1e3:.1f} ms "
             f"({ratios[-1]:.1f}x)")
    if mismatches:
        _say(f"  warning: n={n}: fast and reference cells differed {mismatches} times")
    med = {k: statistics.median(v) * 1e3 for k, v in times.items()}
    return {"size": n, "update_ms": round(med["paper"], 2),
            "visibility_ms": round(med["visibility"], 2),
            "reference_ms": round(med["reference"], 1),
            "speedup": round(statistics.median(ratios), 1),
            "visibility_speedup": round(statistics.median(vis_ratios), 1),
            "cold_ms": round(cold * 1e3, 1), "cell_cells": int(np.median(cells)),
            "searched_nodes": int(np.median(searched)),
            "reference_expanded": int(np.median(expanded)), "cells_match": mismatches == 0}


def bench_scaling(configs: list[tuple[int, int]], updates: int, seed: int) -> list[dict]:
    out = []
    for n, k in configs:
        rng = np.random.default_rng(seed)
        domain = CoverageDomain.from_grid(l_shaped_grid(n), 0.0)
        P = lattice(domain, k, rng)
        own = (k // 2) * k + k // 2
        row: dict[str, float] = {"size": n, "robots": k * k}
        for mode in ("paper", "visibility"):
            cache = SearchCache()
            ts, cells = [], []
            Q = P.copy()
            for _ in range(updates + 1):
                Q = _drift(domain, Q, rng)
                t0 = time.perf_counter()
                res = geodesic_cell(domain, Generator(Q[own]),
                                    [Generator(p) for p in np.delete(Q, own, 0)],
                                    cache=cache, method=mode)
                ts.append(time.perf_counter() - t0)
                cells.append(len(res.nodes))
            row[f"{mode}_ms"] = round(statistics.median(ts[1:]) * 1e3, 2)
            row["cell_cells"] = int(np.median(cells))
        _say(f"  {k * k} robots on {n}x{n}: cell {row['cell_cells']} cells, "
             f"{row['paper_ms']} ms (paper), {row['visibility_ms']} ms (visibility)")
        out.append(row)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[200, 400, 800])
    ap.add_argument("--rounds", type=int, nargs="+", default=[7, 5, 3],
                    help="reference runs per grid (same order as --sizes)")
    ap.add_argument("--per-round", type=int, default=6,
                    help="fast updates before and after each reference run")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-scaling", action="store_true")
    ap.add_argument("--geodesic-scenarios", type=int, default=12,
                    help="random 400 x 400 scenarios for the geodesic team step (default 12)")
    ap.add_argument("--team-step-only", action="store_true",
                    help="only the offline team step on the 'gaussians' world")
    ap.add_argument("--cold-only", action="store_true",
                    help="only the cold update of the largest cell (16 robots on depot)")
    ap.add_argument("--no-results", action="store_true",
                    help="do not write docs/results/core.json (a whole run writes it)")
    args = ap.parse_args(argv)
    from coverage_ros.bench.cold_update import bench_cold_update
    from coverage_ros.bench.geodesic_scale import bench_geodesic_scale, bench_geodesic_sweep
    from coverage_ros.bench.team_step import bench_team_step

    _say("cold update: the largest cell of 16 robots on depot.yaml")
    cold = bench_cold_update(5, _say)
    if args.cold_only:
        print(json.dumps({"cold_update": cold}))
        return 0
    _say("offline team step: 8 robots on world 'gaussians' (402 x 402 cells)")
    team_step = bench_team_step(7, 7, _say)
    _say("geodesic team step at scale and among obstacles")
    team_step["geodesic_scale"] = bench_geodesic_scale(7, _say)
    _say("geodesic team step, 8 robots on random 400 x 400 scenarios")
    team_step["geodesic_sweep"] = bench_geodesic_sweep(args.geodesic_scenarios, 7, _say)
    _say("coverage-plan end to end (process start to JSON) next to the team step")
    end_to_end = _end_to_end(team_step)
    if args.team_step_only:
        print(json.dumps({"team_step": team_step, "end_to_end": end_to_end}))
        return 0
    rounds = (args.rounds + [args.rounds[-1]] * len(args.sizes))[:len(args.sizes)]
    grids = []
    for n, r in zip(args.sizes, rounds, strict=True):
        _say(f"grid {n}x{n}: 9 robots, one robot's update with 8 neighbours")
        row = bench_grid(n, r, args.per_round, args.seed)
        _say(f"  fast {row['update_ms']} ms (paper mode), {row['visibility_ms']} ms (visibility),"
             f" reference {row['reference_ms']} ms, speedup {row['speedup']}x")
        grids.append(row)
    result = {"grids": grids, "team_step": team_step, "end_to_end": end_to_end,
              "cold_update": cold}
    if not args.no_scaling:
        _say("update time against own cell area (k x k robots on n x n cells)")
        result["scaling"] = bench_scaling([(200, 2), (400, 4), (800, 8), (200, 4), (400, 8)],
                                          12, args.seed)
    if not args.no_results:
        from coverage_ros.bench.results import write_results

        write_results("core", {"rows": targets(result), **result}, argv, "scripts/bench_core")
    print(json.dumps(result))
    return 0


def _end_to_end(team_step: dict) -> dict:
    """``coverage-plan --solver lloyd`` on ``gaussians`` as a user runs it, against
    CoverageControl's clairvoyant step (:func:`coverage_ros.bench.planner.bench_end_to_end`;
    ``scripts/bench_planner`` runs more rounds)."""
    from coverage_ros.bench.planner import bench_end_to_end

    e2e = bench_end_to_end(5, _say)
    ours, theirs = e2e["coverage_plan"], e2e["coveragecontrol"]
    _say(f"  team step {team_step['lloyd_ms']} ms; coverage-plan end to end "
         f"{ours['end_to_end_ms_per_step']:.2f} ms/step ({ours['steps']} steps); "
         f"CoverageControl's step {theirs['step_ms']} ms: "
         f"{e2e['ratio_end_to_end_over']['step']:.2f}x")
    return e2e


def targets(result: dict) -> list[dict]:
    """The benchmark's targets, each with its figure and whether it is met."""
    rows = []

    def row(what: str, value: float, unit: str, target: str, met: bool) -> None:
        rows.append({"figure": what, "value": value, "unit": unit, "target": target,
                     "met": bool(met)})

    step = result["team_step"]
    row("offline team step, lloyd (8 robots, 402 x 402 cells)", step["lloyd_ms"], "ms",
        "<= 3 ms", step["lloyd_ms"] <= 3.0)
    row("offline team step, geodesic (8 robots, 402 x 402 cells)", step["geodesic_ms"], "ms",
        "<= 10 ms", step["geodesic_ms"] <= 10.0)
    for s in step.get("geodesic_scale", []):
        W, H = s["grid"]
        row(f"offline team step, geodesic ({s['name']}, {W} x {H} cells)", s["geodesic_ms"],
            "ms", f"<= {s['target_ms']:g} ms", s["met"])
    sweep = step.get("geodesic_sweep")
    for kind, k in (sweep or {}).get("kinds", {}).items():
        row(f"offline team step, geodesic (8 robots, 400 x 400 cells, {k['scenarios']} random "
            f"'{kind}' scenarios): the worst scenario's median", k["worst_ms"], "ms",
            f"<= {sweep['target_ms']:g} ms", k["met"] == k["scenarios"])
    e2e = result.get("end_to_end")
    if e2e is not None:
        ratio = e2e["ratio_end_to_end_over"]["step"]
        row("coverage-plan --solver lloyd end to end, per step, over CoverageControl's step",
            ratio, "x", "<= 1.0x", ratio <= 1.0)
    acc = step["accelerated"]["steps_within_0.1%_of_plain_H"]
    row("accelerated Lloyd: team steps until H within 0.1 % of plain Lloyd's", acc, "steps",
        "<= 60", acc is not None and acc <= 60)
    for g in result["grids"]:
        if g["size"] == 200:
            row("one robot's geodesic update, 200 x 200 cells (paper mode)", g["update_ms"],
                "ms", "<= 10 ms", g["update_ms"] <= 10.0)
            row("its speed-up over the pseudo-code's reference, 200 x 200", g["speedup"], "x",
                ">= 20x", g["speedup"] >= 20.0)
        if g["size"] == 400:
            row("one robot's geodesic update, 400 x 400 cells (paper mode)", g["update_ms"],
                "ms", "<= 50 ms", g["update_ms"] <= 50.0)
    for c in result["cold_update"]:
        if c["configuration"] == "16 robots, start cluster":
            row("first update in the largest cell, 16 robots on depot", c["cold_ms"], "ms",
                "<= 100 ms", c["cold_ms"] <= 100.0)
    return rows


if __name__ == "__main__":
    sys.exit(main())
