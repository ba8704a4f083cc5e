"""The geodesic team step at scale and among obstacles (``scripts/bench_core``, after the team
step on ``gaussians``): :meth:`coverage_ros.core.offline.lloyd_team.GeodesicTeam.step` timed
at positions along a Lloyd run, against its target, and once against
:meth:`~coverage_ros.core.offline.lloyd_team.GeodesicTeam.reference_step` (every robot's own
update over the whole domain, what the team step replaces) at the run's first positions.

* ``gaussians at 1024 x 1024`` - the ``gaussians`` world rasterized at 20 m / 1022 cells
  (1024 x 1024 cells with its wall ring), 32 robots from seeded random free points along a
  plain Lloyd run (:class:`~coverage_ros.core.offline.lloyd_team.EuclideanTeam`); target
  100 ms.
* maps with obstacles, 8 robots from the launcher's start cluster along a geodesic Lloyd run,
  target 10 ms as for 8 robots on 400 x 400 cells: ``depot`` (``../shared/maps``, read where
  it lies: 307 x 604 cells of shelves and walls, a few more cells than 400 x 400),
  ``tb3_sandbox`` (``../shared/maps``: 384 x 384 cells, a SLAM map whose free space fills a
  tenth of its window) and the shipped ``office`` (162 x 242 cells of rooms off a corridor,
  most cells out of sight of every robot).

:func:`bench_geodesic_sweep` then times the same step for 8 robots on random 400 x 400 scenarios
(:func:`coverage_ros.bench.lloyd_sweep.scenario`'s kinds: 1-5 Gaussians, a uniform density, or
4-9 random boxes with a few Gaussians; a start cluster in a random corner; seeds from
:data:`SWEEP_SEEDS_FROM`, never used to tune anything), each along its own geodesic Lloyd run:
the target's 10 ms on scenarios nobody chose, per kind.

A new search every step: the positions drift by a tenth of a millimetre between steps, as
robots do between updates. ``geodesic_ms`` is wall time (the target's measure); ``cpu_ms``,
the process's CPU time over the same steps, shows what a busy host adds; ``dijkstra_ms``, the
wall time of the step's calls to scipy's Dijkstra (the graph searches themselves; the rest is
numpy over the grid: distances, line of sight, the search graphs, sums).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from coverage_ros.bench.environment import DEPOT
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.lloyd_team import EuclideanTeam, GeodesicTeam, solve_lloyd
from coverage_ros.core.world import load_world
from coverage_ros.core.world.loading import parse_world
from coverage_ros.core.world.placement import team_starts
from coverage_ros.worlds import resolve_world_path

#: [cells] side of the large grid; the gaussians world's 20 m over this many cells less its
#: one-cell wall ring on each side
LARGE_CELLS = 1024
LARGE_ROBOTS = 32
MAP_ROBOTS = 8
#: [m] drift of every robot between two timed steps (a new search each time)
DRIFT = 1e-4
SEED = 0
SWEEP_SEEDS_FROM = 9000
SWEEP_ROBOTS = 8
#: [ms] the target of the team step of 8 robots on 400 x 400 cells
SWEEP_TARGET_MS = 10.0


def bench_geodesic_scale(rounds: int, say, depot: Path = DEPOT) -> list[dict]:
    """The rows above, each timed over ``rounds`` positions along its run."""
    rows = []
    domain = _large_gaussians()
    rng = np.random.default_rng(SEED)
    start = _free_points(domain, LARGE_ROBOTS, rng)
    path = solve_lloyd(EuclideanTeam(domain), start, tolerance=0.005, max_steps=60).positions
    rows.append(_row(f"{LARGE_ROBOTS} robots, gaussians rasterized finer", domain, path,
                     rounds, 100.0, say))
    for name, where in (("depot", depot), ("tb3_sandbox", depot.with_name("tb3_sandbox.yaml")),
                        ("office", resolve_world_path("office"))):
        if not where.exists():
            say(f"  {where} not found: the {name} row left out")
            continue
        world = load_world(where)
        specs = [world.robot_spec(i) for i in range(MAP_ROBOTS)]
        domain = world_domain(world, max(s.radius for s in specs))
        start = team_starts(world, specs, None, SEED)[:, :2]
        path = solve_lloyd(GeodesicTeam(domain), start, tolerance=0.05,
                           max_steps=30).positions
        rows.append(_row(f"{MAP_ROBOTS} robots, {name} (obstacles)", domain, path, rounds,
                         10.0, say))
    return rows


def _large_gaussians() -> CoverageDomain:
    path = resolve_world_path("gaussians")
    data = yaml.safe_load(path.read_text())
    data["resolution"] = 20.0 / (LARGE_CELLS - 2)
    world = parse_world(data, source=str(path))
    return world_domain(world, world.robot_spec(0).radius)


def _free_points(domain: CoverageDomain, n: int, rng: np.random.Generator) -> np.ndarray:
    xmin, ymin, xmax, ymax = domain.geometry.extent()
    points: list[np.ndarray] = []
    while len(points) < n:
        p = rng.uniform([xmin, ymin], [xmax, ymax])
        if domain.is_free_point(p):
            points.append(p)
    return np.array(points)


def bench_geodesic_sweep(count: int, rounds: int, say) -> dict[str, Any]:
    """The geodesic team step of 8 robots on ``count`` random 400 x 400 scenarios (module
    docstring), each timed over ``rounds`` positions along its run; rows, and per kind the
    median and worst of the scenarios' median step and how many meet the target."""
    from coverage_ros.bench.lloyd_sweep import scenario

    rows = []
    for i in range(count):
        seed = SWEEP_SEEDS_FROM + i
        domain, starts, about = scenario(seed, i, robots=SWEEP_ROBOTS)
        team = GeodesicTeam(domain)
        path = solve_lloyd(team, starts, tolerance=0.05, max_steps=30).positions
        times, cpu, searches = _timed_steps(team, path, rounds)
        ms = round(statistics.median(times) * 1e3, 2)
        H, W = domain.shape
        rows.append({"seed": seed, "kind": about["kind"], "grid": [W, H], "geodesic_ms": ms,
                     "cpu_ms": round(statistics.median(cpu) * 1e3, 2),
                     "dijkstra_ms": round(statistics.median(searches) * 1e3, 2),
                     "worst_ms": round(max(times) * 1e3, 2), "met": ms <= SWEEP_TARGET_MS})
        say(f"  scenario {i + 1}/{count} (seed {seed}, {about['kind']}): {ms} ms, of which "
            f"Dijkstra {rows[-1]['dijkstra_ms']} ms (worst of {rounds} steps "
            f"{rows[-1]['worst_ms']} ms)")
    kinds = by_kind(rows, SWEEP_TARGET_MS)
    for kind, k in kinds.items():
        say(f"  {kind}: {k['met']} of {k['scenarios']} within {SWEEP_TARGET_MS:g} ms "
            f"(median {k['median_ms']} ms, worst {k['worst_ms']} ms)")
    return {"robots": SWEEP_ROBOTS, "target_ms": SWEEP_TARGET_MS, "steps_timed": rounds,
            "kinds": kinds, "rows": rows}


def by_kind(rows: list[dict], target_ms: float) -> dict[str, dict]:
    """Per scenario kind (in order of first appearance): how many scenarios, the median and
    worst of their ``geodesic_ms`` and how many are within ``target_ms``."""
    kinds = {}
    for kind in dict.fromkeys(r["kind"] for r in rows):
        ms = [r["geodesic_ms"] for r in rows if r["kind"] == kind]
        kinds[kind] = {"scenarios": len(ms), "median_ms": round(statistics.median(ms), 2),
                       "worst_ms": max(ms), "met": sum(v <= target_ms for v in ms)}
    return kinds


def _timed_steps(team: GeodesicTeam, path: np.ndarray,
                 rounds: int) -> tuple[list[float], list[float], list[float]]:
    """Wall and CPU times [s] of ``team``'s step at ``rounds`` positions along ``path``, each
    moved by a drift of its own (a new search every step), and the wall time of each step's
    Dijkstra calls [s]."""
    team.step(path[0] + DRIFT)  # the domain's own tables (graph, tiles, occluders)
    times, cpu, searches = [], [], []
    with _dijkstra_timed() as spent:
        for k in range(rounds):
            P = path[min(k * len(path) // rounds, len(path) - 1)] + DRIFT * (k + 2)
            spent.clear()
            t, c = time.perf_counter(), time.process_time()
            team.step(P)
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            searches.append(sum(spent))
    return times, cpu, searches


@contextmanager
def _dijkstra_timed() -> Iterator[list[float]]:
    """While open, every call to scipy's Dijkstra from the team step's modules appends its wall
    time [s] to the list it yields (the modules' own name for it swapped, then put back)."""
    from scipy.sparse.csgraph import dijkstra

    from coverage_ros.core.geodesic import descent, shared_search, visible_first
    from coverage_ros.core.offline import geodesic_team

    modules = (descent, shared_search, visible_first, geodesic_team)
    plain = [m.dijkstra for m in modules]
    spent: list[float] = []

    def timed(*args: Any, **kwargs: Any) -> Any:
        t = time.perf_counter()
        try:
            return dijkstra(*args, **kwargs)
        finally:
            spent.append(time.perf_counter() - t)

    for m in modules:
        m.dijkstra = timed  # type: ignore[attr-defined]
    try:
        yield spent
    finally:
        for m, f in zip(modules, plain, strict=True):
            m.dijkstra = f  # type: ignore[attr-defined]


def _row(name: str, domain: CoverageDomain, path: np.ndarray, rounds: int,
         target_ms: float, say) -> dict[str, Any]:
    team = GeodesicTeam(domain)
    times, cpu, searches = _timed_steps(team, path, rounds)
    t = time.perf_counter()
    team.reference_step(path[0])
    reference = time.perf_counter() - t
    ms = round(statistics.median(times) * 1e3, 2)
    H, W = domain.shape
    row = {"name": name, "robots": len(path[0]), "grid": [W, H], "geodesic_ms": ms,
           "cpu_ms": round(statistics.median(cpu) * 1e3, 2),
           "dijkstra_ms": round(statistics.median(searches) * 1e3, 2), "target_ms": target_ms,
           "met": ms <= target_ms,
           "robots_ms": round(reference * 1e3, 1), "steps_timed": rounds}
    say(f"  geodesic team step, {name} ({W} x {H} cells): {ms} ms, CPU {row['cpu_ms']} ms, "
        f"Dijkstra {row['dijkstra_ms']} ms "
        f"({'met' if row['met'] else 'not met'}: <= {target_ms:g} ms); every robot's own "
        f"update {row['robots_ms']} ms")
    return row
