"""A robot's first (cold) coverage update in the largest cell of a big team (``scripts/
bench_core``, section "cold update"; ``--cold-only`` runs just this).

16 robots on ``../shared/maps/depot.yaml`` (5 cm cells, TurtleBot3 radius) in the launcher's
start cluster, and the same team spread out by the geodesic Lloyd team step; then 64 robots in
the launcher's start cluster. In each configuration the robot with the largest cell updates
with a fresh search cache (a robot that just started, or restarted), timed over rounds; the
64-robot row also gives the slowest robot's cold update. Against it, in the same process:

* ``warm_ms`` - the next update of the same robot (its cache holds the search region);
* ``reference_ms`` - the centralized tessellation of the whole map
  (:func:`coverage_ros.core.geodesic.tessellation.tessellate`: one multi-source Dijkstra over
  every free cell, what the parity tests compare every robot's own cell with).
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from coverage_ros.bench.environment import DEPOT
from coverage_ros.core.geodesic.cell import CellResult, SearchCache, geodesic_cell
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tessellation import Generator, tessellate
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.lloyd_team import GeodesicTeam, solve_lloyd
from coverage_ros.core.world import load_world
from coverage_ros.core.world.placement import team_starts

ROBOTS = 16
SEED = 0  # the launcher's default start cluster


def _largest(domain: CoverageDomain, P: np.ndarray) -> int:
    labels = tessellate(domain, [Generator(p) for p in P]).labels
    return int(np.argmax(np.bincount(labels[labels >= 0].ravel(), minlength=len(P))))


def bench_cold_update(rounds: int, say, world_path: Path = DEPOT) -> list[dict]:
    world = load_world(world_path)
    specs = [world.robot_spec(i) for i in range(ROBOTS)]
    domain = world_domain(world, max(s.radius for s in specs))
    start = team_starts(world, specs, None, SEED)[:, :2]
    say(f"  spreading {ROBOTS} robots on {world_path.name} (geodesic team steps)")
    spread = solve_lloyd(GeodesicTeam(domain), start, tolerance=0.05, max_steps=40).positions[-1]
    rows = [_row(domain, "16 robots, start cluster", start, rounds, say),
            _row(domain, "16 robots, spread", spread, rounds, say)]
    specs = [world.robot_spec(i) for i in range(64)]
    cluster = team_starts(world, specs, None, SEED)[:, :2]
    rows.append(_row(domain, "64 robots, start cluster", cluster, rounds, say, slowest=True))
    return rows


def _cold(domain: CoverageDomain, gens: list[Generator], k: int) -> tuple[float, CellResult]:
    """One cold update of robot ``k``: [s] and its result. A whole-map search is memoized per
    generator set (robots of one process that see the same team share it); a robot's next
    update has moved, so it is forgotten first (and the depth maps its searches keep by
    generator position)."""
    _forget(domain)
    t = time.perf_counter()
    cell = geodesic_cell(domain, gens[k], gens[:k] + gens[k + 1:], cache=SearchCache())
    return time.perf_counter() - t, cell


def _forget(domain: CoverageDomain) -> None:
    """Drop what the last update memoized for the next: the whole-map search of the same
    generators, and the depth maps kept by position."""
    domain._cache.pop("shared_search", None)
    domain._cache.pop("kept_depth_maps", None)


def _row(domain: CoverageDomain, name: str, P: np.ndarray, rounds: int, say,
         slowest: bool = False) -> dict:
    gens = [Generator(p) for p in P]
    k = _largest(domain, P)
    own, others = gens[k], gens[:k] + gens[k + 1:]
    _cold(domain, gens, k)  # the domain's own tables
    cold, warm, ref = [], [], []
    for _ in range(rounds):
        dt, cell = _cold(domain, gens, k)
        cold.append(dt)
        cache = SearchCache()
        geodesic_cell(domain, own, others, cache=cache)
        _forget(domain)
        t = time.perf_counter()
        geodesic_cell(domain, own, others, cache=cache)
        warm.append(time.perf_counter() - t)
        t = time.perf_counter()
        tess = tessellate(domain, gens)
        ref.append(time.perf_counter() - t)
        assert np.array_equal(np.sort(cell.nodes), np.flatnonzero(tess.labels.ravel() == k))
    row: dict[str, Any] = {"configuration": name, "cell_cells": int(len(cell.nodes)),
           "map_free_cells": int(domain.free.sum()), "passes": cell.passes,
           "cold_ms": round(1e3 * statistics.median(cold), 1),
           "warm_ms": round(1e3 * statistics.median(warm), 1),
           "reference_ms": round(1e3 * statistics.median(ref), 1)}
    row["speedup_over_reference"] = round(row["reference_ms"] / row["cold_ms"], 1)
    text = (f"  {name}: largest cell {row['cell_cells']} of {row['map_free_cells']} cells; "
            f"cold {row['cold_ms']} ms ({cell.passes} pass(es)), warm {row['warm_ms']} ms, "
            f"centralized tessellation {row['reference_ms']} ms")
    if slowest:
        times = [(_cold(domain, gens, i)[0], i) for i in range(len(gens))]
        worst, who = max(times)
        row["slowest_cold_ms"], row["slowest_robot"] = round(1e3 * worst, 1), who
        row["median_cold_ms"] = round(1e3 * statistics.median(t for t, _ in times), 1)
        text += (f"; every robot's cold update: median {row['median_cold_ms']} ms, slowest "
                 f"{row['slowest_cold_ms']} ms (robot {who})")
    say(text)
    return row
