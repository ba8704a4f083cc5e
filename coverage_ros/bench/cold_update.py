"""A robot's first (cold) coverage update in the largest cell of a big team (``scripts/
bench_core``, section "cold update"; ``--cold-only`` runs just this).

16 robots on ``../shared/maps/depot.yaml`` (5 cm cells, TurtleBot3 radius) in the launcher's
start cluster, and the same team spread out by the geodesic Lloyd team step. In each
configuration the robot with the largest cell updates with a fresh search cache (a robot that
just started, or restarted), timed over rounds; against it, in the same process:

* ``warm_ms`` - the next update of the same robot (its cache holds the search region);
* ``previous_rule_ms`` - the cold update started from the search radius of the rule before
  :func:`coverage_ros.core.geodesic.cell.cold_radius` (0.6 x the distance to the 4th nearest
  neighbour, given as the cache's radius hint), which grows by 1.6x per pass until the cell
  fits.
"""

from __future__ import annotations

import math
import statistics
import time
from pathlib import Path

import numpy as np

from coverage_ros.core.geodesic.cell import SearchCache, geodesic_cell
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tessellation import Generator, tessellate
from coverage_ros.core.offline.lloyd_team import GeodesicTeam, solve_lloyd
from coverage_ros.core.world import load_world
from coverage_ros.core.world.placement import team_starts

DEPOT = Path(__file__).resolve().parents[2].parent / "shared" / "maps" / "depot.yaml"
ROBOTS = 16
SEED = 0  # the launcher's default start cluster


def _previous_rule(domain: CoverageDomain, own: Generator, others: list[Generator]) -> float:
    d = np.sort([domain.metric_lower_bound * math.hypot(*(o.position - own.position))
                 for o in others])
    return max(0.6 * d[min(len(d), 4) - 1], 4.0 * domain.graph.max_edge_cost)


def _largest(domain: CoverageDomain, P: np.ndarray) -> int:
    labels = tessellate(domain, [Generator(p) for p in P]).labels
    return int(np.argmax(np.bincount(labels[labels >= 0].ravel(), minlength=len(P))))


def bench_cold_update(rounds: int, say, world_path: Path = DEPOT) -> list[dict]:
    world = load_world(world_path)
    specs = [world.robot_spec(i) for i in range(ROBOTS)]
    domain = CoverageDomain.from_world(world, max(s.radius for s in specs))
    start = team_starts(world, specs, None, SEED)[:, :2]
    say(f"  spreading {ROBOTS} robots on {world_path.name} (geodesic team steps)")
    spread = solve_lloyd(GeodesicTeam(domain), start, tolerance=0.05, max_steps=40).positions[-1]
    rows = []
    for name, P in (("start cluster", start), ("spread", spread)):
        k = _largest(domain, P)
        gens = [Generator(p) for p in P]
        own, others = gens[k], gens[:k] + gens[k + 1:]
        geodesic_cell(domain, own, others, cache=SearchCache())  # the domain's own tables
        cold, warm, old, passes = [], [], [], 0
        for _ in range(rounds):
            # A whole-map search is memoized per generator set (robots of one process that
            # see the same team share it); a robot's next update has moved: never a hit here.
            forget = lambda: domain._cache.pop("shared_search", None)  # noqa: E731
            cache = SearchCache()
            forget()
            t = time.perf_counter()
            cell = geodesic_cell(domain, own, others, cache=cache)
            cold.append(time.perf_counter() - t)
            passes = cell.passes
            forget()
            t = time.perf_counter()
            geodesic_cell(domain, own, others, cache=cache)
            warm.append(time.perf_counter() - t)
            cache = SearchCache()
            cache.cell_radius = _previous_rule(domain, own, others)
            forget()
            t = time.perf_counter()
            ref = geodesic_cell(domain, own, others, cache=cache)
            old.append(time.perf_counter() - t)
            assert np.array_equal(np.sort(ref.nodes), np.sort(cell.nodes))
        row = {"configuration": name, "cell_cells": int(len(cell.nodes)),
               "map_free_cells": int(domain.free.sum()), "passes": passes,
               "previous_rule_passes": ref.passes,
               "cold_ms": round(1e3 * statistics.median(cold), 1),
               "warm_ms": round(1e3 * statistics.median(warm), 1),
               "previous_rule_ms": round(1e3 * statistics.median(old), 1)}
        row["speedup_over_previous_rule"] = round(row["previous_rule_ms"] / row["cold_ms"], 1)
        say(f"  {name}: largest cell {row['cell_cells']} of {row['map_free_cells']} cells; "
            f"cold {row['cold_ms']} ms ({passes} pass(es)), warm {row['warm_ms']} ms, previous "
            f"rule {row['previous_rule_ms']} ms ({ref.passes} passes)")
        rows.append(row)
    return rows
