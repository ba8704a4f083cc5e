"""The accelerated team Lloyd solver against plain Lloyd on random scenarios
(``scripts/bench_planner``).

Every scenario is drawn from its seed alone: a 20 m square at 5 cm with a density of 1-5
Gaussians (widths 0.5-5 m), a uniform density, or random box obstacles with a few Gaussians;
8, 16 or 32 robots starting in a cluster in a random corner. Kinds and team sizes take turns so
that every seed set has each pairing. Two disjoint seed sets: ``train`` (what the solver was
tuned on) and ``held-out`` (what is reported). The team step is plain Lloyd's Euclidean cells, or
(``team="geodesic"``) the geodesic power cells of ``coverage-plan --strategy geodesic``.

Per scenario, both solvers from the same starts until no robot moves more than ``TOLERANCE``:

* ``steps`` - tessellations to converge (an accelerated solver's rejected tries count);
* ``steps_within`` - tessellations until H was within 0.1 % of plain Lloyd's final H;
* ``gap`` - final H / plain Lloyd's final H - 1;
* ``plain_nudged`` - plain Lloyd again from starts moved by :data:`NUDGE` (1 mm): its gap and
  steps against plain Lloyd's own run, the spread of the end that the landscape alone makes
  (many local minima a few tenths of a percent apart), for scale.

Summary: the median over scenarios of accelerated / plain steps to converge and of accelerated
steps within 0.1 % over plain's steps to converge (and over plain's own steps within 0.1 %), the
worst (largest) of these ratios, the H gaps and how many scenarios end above +0.1 %. The
targets: the median and the worst case of steps to within 0.1 % over plain's steps (<= 0.5,
<= 1), the largest gap (<= 0.1 %), and, a stricter reading of the worst case, steps to converge
(<= plain's: an accelerated run that goes on into a lower minimum than plain's counts as
slower).

``scripts/bench_planner --settled S`` runs the sweep with another switch threshold of the
accelerated solver (:data:`~coverage_ros.core.offline.lloyd_solvers.SETTLED` by default).
"""

from __future__ import annotations

import math
import statistics
import time

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.offline.lloyd_solvers import SETTLED
from coverage_ros.core.offline.lloyd_team import EuclideanTeam, GeodesicTeam, solve_lloyd
from coverage_ros.core.world.density import Density, GaussianMixture, UniformDensity
from coverage_ros.core.world.grid import OCCUPIED, GridMap

SIDE = 20.0  # [m]
RESOLUTION = 0.05  # [m]
RADIUS = 0.105  # [m] robot radius: the free space is inflated by it
TOLERANCE = 1e-4  # [m]
MAX_STEPS = 3000
KINDS = ("gaussians", "uniform", "gaussians", "obstacles")
TEAMS = (8, 16, 32)
SEEDS = {"train": 1000, "held-out": 5000}
#: [m] plain Lloyd's own spread (``plain_nudged``): the scenario again from starts moved this
#: far in seeded directions, against plain Lloyd - how far its end moves with the starts alone.
NUDGE = 1e-3
#: the team steps a sweep may compare the solvers with: Euclidean Voronoi cells (plain
#: ``coverage-plan --strategy lloyd``), or geodesic power cells (``--strategy geodesic``)
TEAM_STEPS = {"lloyd": EuclideanTeam, "geodesic": GeodesicTeam}


def scenario(seed: int, index: int,
             robots: int | None = None) -> tuple[CoverageDomain, np.ndarray, dict]:
    """The domain, starts (n, 2) [m] and a description of scenario ``index`` drawn from
    ``seed`` (``robots``: that team size instead of the index's)."""
    rng = np.random.default_rng(seed)
    kind = KINDS[index % len(KINDS)]
    robots = TEAMS[index % len(TEAMS)] if robots is None else robots
    cells = int(round(SIDE / RESOLUTION))
    occ = np.zeros((cells, cells), dtype=np.int8)
    if kind == "obstacles":
        for _ in range(int(rng.integers(4, 10))):
            w, h = rng.uniform(0.5, 4.0, 2)
            x, y = rng.uniform(2.0, SIDE - 2.0, 2)
            c0, c1 = int((x - w / 2) / RESOLUTION), int((x + w / 2) / RESOLUTION)
            r0, r1 = int((y - h / 2) / RESOLUTION), int((y + h / 2) / RESOLUTION)
            occ[max(r0, 0):r1, max(c0, 0):c1] = OCCUPIED
    grid = GridMap(occ, RESOLUTION, (0.0, 0.0, 0.0))
    density: Density
    if kind == "uniform":
        density, parts = UniformDensity(), []
    else:
        k = int(rng.integers(1, 6)) if kind == "gaussians" else int(rng.integers(1, 4))
        means = rng.uniform(1.0, SIDE - 1.0, (k, 2))
        sigmas = rng.uniform(0.5, 5.0, (k, 2))
        weights = rng.uniform(0.5, 1.5, k)
        density = GaussianMixture(means, np.array([np.diag(s ** 2) for s in sigmas]), weights)
        parts = [{"mean": m.round(2).tolist(), "sigma": s.round(2).tolist(), "weight": round(
            float(w), 2)} for m, s, w in zip(means, sigmas, weights, strict=True)]
    domain = CoverageDomain.from_grid(grid, RADIUS, density)
    corner = rng.integers(0, 2, 2) * SIDE
    inward = np.where(corner > 0, -1.0, 1.0)
    reach = 0.6 * np.sqrt(robots)  # [m] a cluster about 0.5 m apart
    starts: list[np.ndarray] = []
    misses = 0
    while len(starts) < robots:
        p = corner + inward * (0.4 + rng.uniform(0.0, reach, 2))
        if domain.is_free_point(p) and all(np.hypot(*(p - q)) > 0.3 for q in starts):
            starts.append(p)
            misses = 0
        else:
            misses += 1
            if misses == 5000:  # an obstacle fills the corner: a wider cluster
                reach, misses = 1.2 * reach, 0
    about = {"seed": seed, "kind": kind, "robots": robots, "corner": corner.tolist(),
             "gaussians": parts}
    return domain, np.array(starts), about


def compare(domain: CoverageDomain, starts: np.ndarray, solvers=("lloyd", "accelerated"),
            team: str = "lloyd", **options) -> dict:
    """Both solvers from ``starts`` with the ``team`` step (:data:`TEAM_STEPS`); steps, steps
    within 0.1 % of plain's H, H gaps, times."""
    step = TEAM_STEPS[team](domain)
    runs, walls = {}, {}
    for solver in solvers:
        t0 = time.perf_counter()
        runs[solver] = solve_lloyd(step, starts, solver=solver, tolerance=TOLERANCE,
                                   max_steps=MAX_STEPS, **options.get(solver, {}))
        walls[solver] = time.perf_counter() - t0
    ref = runs["lloyd"]
    out = {}
    for solver, r in runs.items():
        out[solver] = {"steps": r.steps, "converged": r.converged, "H": r.cost,
                       "steps_within": r.steps_within(ref.cost),
                       "gap": r.cost / ref.cost - 1.0, "wall_s": round(walls[solver], 3)}
    return out


def nudged(domain: CoverageDomain, starts: np.ndarray, seed: int) -> np.ndarray:
    """``starts`` each moved by :data:`NUDGE` in a direction drawn from ``seed`` (the other
    way, or not at all, where that leaves the free space)."""
    angle = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, len(starts))
    step = NUDGE * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    out = starts.copy()
    for k, p in enumerate(starts):
        out[k] = next((q for q in (p + step[k], p - step[k]) if domain.is_free_point(q)), p)
    return out


def run_sweep(seed_set: str, count: int, say, solvers=("lloyd", "accelerated"),
              team: str = "lloyd", **options) -> dict:
    """``count`` scenarios of ``seed_set``, each compared (module docstring) with the ``team``
    step, and plain Lloyd from starts nudged by :data:`NUDGE`; a summary."""
    base = SEEDS[seed_set]
    rows = []
    for i in range(count):
        seed = base + i
        domain, starts, about = scenario(seed, i)
        res = compare(domain, starts, solvers, team, **options)
        p, a = res["lloyd"], res[solvers[-1]]
        again = solve_lloyd(TEAM_STEPS[team](domain), nudged(domain, starts, seed),
                            tolerance=TOLERANCE, max_steps=MAX_STEPS)
        row = {**about, "plain": p, "accelerated": a,
               "ratio_steps": a["steps"] / p["steps"],
               "ratio_within": (a["steps_within"] or a["steps"]) / p["steps"],
               "ratio_within_own": (a["steps_within"] or a["steps"]) / p["steps_within"],
               "plain_nudged": {"steps": again.steps, "converged": again.converged,
                                "gap": again.cost / p["H"] - 1.0,
                                "ratio_steps": again.steps / p["steps"]}}
        rows.append(row)
        say(f"  seed {seed}: {about['kind']:9s} {about['robots']:2d} robots: plain "
            f"{p['steps']:4d} steps ({p['steps_within']} within 0.1 %), accelerated "
            f"{a['steps']:4d} ({a['steps_within']}), steps {row['ratio_steps']:.2f}, "
            f"within {row['ratio_within']:.2f}, H gap {100 * a['gap']:+.3f} %; plain nudged "
            f"{again.steps} steps, H gap {100 * row['plain_nudged']['gap']:+.3f} %")
    summary = summarize(rows)
    say(f"  {seed_set}: median accelerated / plain steps {summary['median_ratio_steps']:.2f} "
        f"(worst {summary['worst_ratio_steps']:.2f}); within 0.1 % of plain's H after "
        f"{summary['median_ratio_within']:.2f} of plain's steps (worst "
        f"{summary['worst_ratio_within']:.2f}; {summary['median_ratio_within_own']:.2f} of "
        f"plain's own steps to within 0.1 %); H gap median {summary['median_gap_percent']:+.4f}"
        f" %, largest {summary['max_gap_percent']:+.4f} % ({summary['above_0.1%']} of "
        f"{len(rows)} scenarios above +0.1 %, {summary['below_0.1%']} below -0.1 %, mean "
        f"{summary['mean_gap_percent']:+.4f} %)")
    spread = summary["plain_nudged"]
    say(f"  plain Lloyd from starts moved {1e3 * NUDGE:g} mm: H gap to its own run "
        f"{spread['min_gap_percent']:+.4f} % to {spread['max_gap_percent']:+.4f} % "
        f"({spread['above_0.1%']} scenarios above +0.1 %, {spread['below_0.1%']} below -0.1 %, "
        f"mean {spread['mean_gap_percent']:+.4f} %), steps worst "
        f"{spread['worst_ratio_steps']:.2f} ({spread['slower']} scenarios slower)")
    met = summary["targets_met"]
    targets = [
        {"target": "median steps to within 0.1 % of plain's final H <= 0.5 x plain's steps",
         "value": summary["median_ratio_within"],
         "met": met["median_within_0.1%_in_half_plain_steps"]},
        {"target": "final H never more than 0.1 % above plain's", "value": f"largest gap "
         f"{summary['max_gap_percent']:+.4f} % ({summary['above_0.1%']} of {len(rows)} "
         f"scenarios above +0.1 %, {summary['below_0.1%']} below -0.1 %, mean gap "
         f"{summary['mean_gap_percent']:+.3f} %; plain from starts 1 mm away: "
         f"{spread['above_0.1%']} above, {spread['below_0.1%']} below, mean "
         f"{spread['mean_gap_percent']:+.3f} %)",
         "met": met["never_more_than_0.1%_above_plain_H"]},
        {"target": "worst case steps to within 0.1 % of plain's final H <= plain's steps",
         "value": summary["worst_ratio_within"],
         "met": met["worst_case_within_0.1%_no_slower_than_plain"]},
        {"target": "worst case steps to converge <= plain's (stricter: the accelerated run "
         "may go on into a lower minimum)", "value": summary["worst_ratio_steps"],
         "met": met["worst_case_no_slower_than_plain"]}]
    settled = options.get("accelerated", {}).get("settled", SETTLED)
    return {"seed_set": seed_set, "team": team, "seeds": [r["seed"] for r in rows],
            "tolerance_m": TOLERANCE,
            "settled": settled, "targets": targets, "summary": summary, "scenarios": rows}


def summarize(rows: list[dict]) -> dict:
    def col(key: str) -> list[float]:
        return [r[key] for r in rows]

    gaps = [100 * r["accelerated"]["gap"] for r in rows]
    spread = [r["plain_nudged"] for r in rows if "plain_nudged" in r]
    nudged_gaps = [100 * n["gap"] for n in spread]
    return {"scenarios": len(rows),
            # plain Lloyd against itself from starts 1 mm away: the landscape's own spread
            "plain_nudged": {"nudge_m": NUDGE,
                             "max_gap_percent": max(nudged_gaps, default=math.nan),
                             "min_gap_percent": min(nudged_gaps, default=math.nan),
                             "above_0.1%": sum(g > 0.1 for g in nudged_gaps),
                             "below_0.1%": sum(g < -0.1 for g in nudged_gaps),
                             "mean_gap_percent": (statistics.fmean(nudged_gaps)
                                                  if nudged_gaps else math.nan),
                             "worst_ratio_steps": max((n["ratio_steps"] for n in spread),
                                                      default=math.nan),
                             "slower": sum(n["ratio_steps"] > 1.0 for n in spread)},
            "median_ratio_steps": statistics.median(col("ratio_steps")),
            "worst_ratio_steps": max(col("ratio_steps")),
            "median_ratio_within": statistics.median(col("ratio_within")),
            "worst_ratio_within": max(col("ratio_within")),
            "median_ratio_within_own": statistics.median(col("ratio_within_own")),
            "worst_ratio_within_own": max(col("ratio_within_own")),
            "median_gap_percent": statistics.median(gaps), "max_gap_percent": max(gaps),
            "min_gap_percent": min(gaps), "above_0.1%": sum(g > 0.1 for g in gaps),
            # ends in a lower minimum than plain's (the other side of the same spread)
            "below_0.1%": sum(g < -0.1 for g in gaps), "mean_gap_percent": statistics.fmean(gaps),
            "all_converged": all(r["plain"]["converged"] and r["accelerated"]["converged"]
                                 for r in rows),
            "targets_met": {
                "median_within_0.1%_in_half_plain_steps": statistics.median(
                    col("ratio_within")) <= 0.5,
                "never_more_than_0.1%_above_plain_H": max(gaps) <= 0.1,
                "worst_case_within_0.1%_no_slower_than_plain": max(col("ratio_within")) <= 1.0,
                "worst_case_no_slower_than_plain": max(col("ratio_steps")) <= 1.0}}
