"""``coverage-plan`` end to end against CoverageControl on random scenarios of its kind
(``scripts/bench_planner --e2e-scenarios N``).

Every scenario is drawn from its seed alone: a 20 m square with its wall ring at 5 cm (402 x 402
cells) or at 20 m / 1022 (1024 x 1024 cells, CoverageControl's default map size), a density of
1-5 Gaussians (widths 0.5-5 m, round or axis-aligned, weights 0.5-1.5) and 8, 16 or 32 robots
in a cluster in a random corner; team sizes take turns, and every three scenarios give one of
them the large grid (each team size gets it in turn).
The seeds (from :data:`SEEDS_FROM`) were never used to tune anything.

Per scenario, :func:`coverage_ros.bench.planner.bench_end_to_end` in rounds side by side
(:func:`coverage_ros.bench.planner.bench_sweep`). A process's fixed cost (start-up, imports,
reading the world, building the domain, the JSON) is what its wall time leaves beside its steps;
``break_even_steps`` is how many steps a run needs before its end-to-end time per step is at most
CoverageControl's step: a run that converges in fewer (a team already near its cells) cannot
meet the target, whatever the step costs, since the Python interpreter and numpy alone start in
about 80 ms. So each row also sets the two processes side by side, start to exit each
(``ratio_end_to_end``: ours over CoverageControl's end-to-end time per step), which pays its own
interpreter, imports and world.
"""

from __future__ import annotations

import math
import statistics
from typing import Any

import numpy as np

SEEDS_FROM = 7000
SIDE = 20.0  # [m]
TEAMS = (8, 16, 32)
#: [cells] the grid sides, walls included: world gaussians' 5 cm and CoverageControl's 1024
CELLS = (402, 1024)
#: [m] least distance between two starts of a cluster (two robot radii and a gap)
SPACING = 0.35
#: [m] the cluster's distance from the walls
MARGIN = 0.5


def draw(seed: int, index: int) -> tuple[dict[str, Any], int, int]:
    """The world mapping of scenario ``index`` of a sweep (``seed``), its robots and its
    grid side in cells."""
    rng = np.random.default_rng(seed)
    robots = TEAMS[index % len(TEAMS)]
    cells = CELLS[1] if (index + index // 3) % 3 == 2 else CELLS[0]  # (each team on both)
    components = []
    for _ in range(int(rng.integers(1, 6))):
        mean = [round(float(v), 3) for v in rng.uniform(2.0, SIDE - 2.0, 2)]
        width = round(float(rng.uniform(0.5, 5.0)), 3)  # [m]
        sigma: float | list[float] = width
        if rng.random() < 0.5:
            sigma = [width, round(float(rng.uniform(0.5, 5.0)), 3)]
        components.append({"mean": mean, "sigma": sigma,
                           "weight": round(float(rng.uniform(0.5, 1.5)), 3)})
    side = 0.6 * math.sqrt(robots) + 1.0  # [m] the cluster's square
    corner = rng.integers(0, 2, 2)  # (0: low side, 1: high side) along x and y
    low = np.where(corner == 1, SIDE - MARGIN - side, MARGIN)
    starts: list[np.ndarray] = []
    while len(starts) < robots:
        p = low + rng.uniform(0.0, side, 2)
        if all(float(np.hypot(*(p - q))) >= SPACING for q in starts):
            starts.append(p)
    world = {"name": f"coveragecontrol-kind-{seed}", "resolution": SIDE / (cells - 2),
             "bounds": [0.0, 0.0, SIDE, SIDE],
             "density": {"type": "gaussian_mixture", "components": components},
             "robots": [[round(float(x), 3), round(float(y), 3), 0.0] for x, y in starts]}
    return world, robots, cells


def row(seed: int, cells: int, world: dict, robots: int, result: dict) -> dict:
    """A scenario's row from :func:`coverage_ros.bench.planner.bench_end_to_end`'s ``result``:
    our figures, CoverageControl's step, the ratio, the fixed cost and the break-even steps."""
    ours = result["coverage_plan"]
    out: dict[str, Any] = {
        "seed": seed, "cells": cells, "robots": robots,
        "gaussians": len(world["density"]["components"]), "steps": ours["steps"],
        "end_to_end_ms_per_step": ours["end_to_end_ms_per_step"], "step_ms": ours["step_ms"],
        # [ms] what the process spends beside its steps
        "fixed_ms": round(ours["wall_s"] * 1e3 - ours["steps"] * ours["step_ms"], 1)}
    theirs = result["coveragecontrol"]
    if "not_installed" in theirs:
        return out
    out.update({"cc_steps": theirs["steps"], "cc_step_ms": theirs["step_ms"],
                "ratio": result["ratio_end_to_end_over"]["step"]})
    if "end_to_end" in result["ratio_end_to_end_over"]:  # (process against process)
        out.update({"cc_end_to_end_ms_per_step": theirs["end_to_end_ms_per_step"],
                    "ratio_end_to_end": result["ratio_end_to_end_over"]["end_to_end"]})
    gain = theirs["step_ms"] - ours["step_ms"]  # [ms] per step
    out["break_even_steps"] = math.ceil(out["fixed_ms"] / gain) if gain > 0 else None
    out["met"] = out["ratio"] <= 1.0
    return out


def targets(summary: dict) -> list[dict]:
    """The targets as the results page shows them: end to end at most CoverageControl's step
    on every scenario compared, and at most its process's own end-to-end time per step."""
    if not summary.get("compared"):
        return []
    out = [{"target": "end-to-end ms/step <= CoverageControl's step, every scenario",
            "value": f"{summary['met']} of {summary['compared']} (ratio median "
                     f"{summary['median_ratio']:g}, worst {summary['worst_ratio']:g}; the "
                     f"runs not met took at most {summary['most_steps_not_met']} steps)",
            "met": summary["met"] == summary["compared"]}]
    if "met_end_to_end" in summary:
        out.append({"target": "end-to-end ms/step <= CoverageControl's end-to-end ms/step "
                              "(process start to exit, both), every scenario",
                    "value": f"{summary['met_end_to_end']} of {summary['compared']} (ratio "
                             f"median {summary['median_ratio_end_to_end']:g}, worst "
                             f"{summary['worst_ratio_end_to_end']:g})",
                    "met": summary["met_end_to_end"] == summary["compared"]})
    return out


def summarize(rows: list[dict]) -> dict:
    """How many scenarios meet the target (end to end <= CoverageControl's step), the median
    and worst ratio, and the fewest steps among those met and those not."""
    timed = [r for r in rows if "ratio" in r]
    if not timed:
        return {"scenarios": len(rows), "compared": 0}
    ratios = [r["ratio"] for r in timed]
    met = [r for r in timed if r["met"]]
    missed = [r for r in timed if not r["met"]]
    out = {"scenarios": len(rows), "compared": len(timed), "met": len(met),
           "median_ratio": round(statistics.median(ratios), 3),
           "worst_ratio": round(max(ratios), 3),
           "median_fixed_ms": round(statistics.median(r["fixed_ms"] for r in timed), 1),
           "most_steps_not_met": max((r["steps"] for r in missed), default=None),
           "fewest_steps_met": min((r["steps"] for r in met), default=None)}
    whole = [r["ratio_end_to_end"] for r in timed if "ratio_end_to_end" in r]
    if len(whole) == len(timed):
        out.update({"met_end_to_end": sum(v <= 1.0 for v in whole),
                    "median_ratio_end_to_end": round(statistics.median(whole), 3),
                    "worst_ratio_end_to_end": round(max(whole), 3)})
    return out
