"""Offline team step on the scale scenario (``scripts/bench_core``; world ``gaussians``: 20 m x
20 m at 5 cm, three Gaussians, eight robots starting in a corner).

* ``lloyd_ms`` - the whole team's vectorized Lloyd step
  (:class:`coverage_ros.core.offline.lloyd_team.EuclideanTeam`), against ``lloyd_robots_ms``,
  the same step as eight decentralized ``lloyd`` updates (what ``coverage-plan
  --solver decentralized`` and the robots run), timed interleaved in rounds on the same
  positions; ``lloyd_speedup`` is the median over rounds of their ratio.
* ``geodesic_ms`` - the geodesic team step (:class:`coverage_ros.core.offline.lloyd_team.
  GeodesicTeam`: one tessellation - one search, cells settled by line of sight first, every
  robot's sums and control at once; target 10 ms) against
  ``geodesic_robots_ms``, the eight robots' own decentralized geodesic updates (the ``coverage-plan
  --strategy geodesic --solver decentralized`` iteration), at positions of the plain Lloyd run;
  then plain and accelerated generalized Lloyd with the geodesic team step.
* ``plain`` / ``accelerated`` - :func:`coverage_ros.core.offline.lloyd_team.solve_lloyd` from the
  corner: tessellations to converge, tessellations until H was within 0.1 % of the plain run's
  final H, final H and wall time.
"""

from __future__ import annotations

import itertools
import statistics
import time

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.euclidean import euclidean_cell
from coverage_ros.core.geodesic.tessellation import Generator
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.lloyd_team import EuclideanTeam, GeodesicTeam, solve_lloyd
from coverage_ros.core.strategies import (
    Neighbour,
    Observation,
    SharedState,
    StrategyContext,
    make_strategy,
    strategy_choice,
)
from coverage_ros.core.world import load_world
from coverage_ros.worlds import resolve_world_path

WORLD = "gaussians"


def _robots_step(domain: CoverageDomain, P: np.ndarray) -> list:
    gens = [Generator(p) for p in P]
    return [euclidean_cell(domain, g, gens[:i] + gens[i + 1:]) for i, g in enumerate(gens)]


def _geodesic_step(robots: list, P: np.ndarray) -> None:
    shared = [SharedState(position=p.copy(), weight=0.0, mass=0.0) for p in P]
    for i, robot in enumerate(robots):
        obs = Observation(i, np.array([*P[i], 0.0]), 0.0)
        robot.update(obs, [Neighbour(j, shared[j]) for j in range(len(P)) if j != i])


def _interleaved(path: np.ndarray, rounds: int, per_round: int, fast, slow) -> tuple:
    """Rounds at positions along ``path``: ``per_round`` calls of ``fast``, one of ``slow``;
    the median times [ms] and the median over rounds of their ratio (the host's speed
    changes stay out of it)."""
    f_all, s_all, ratios = [], [], []
    for k in range(rounds):
        P = path[min(k * len(path) // rounds, len(path) - 1)]
        f = []
        for _ in range(per_round):
            t = time.perf_counter()
            fast(P)
            f.append(time.perf_counter() - t)
        t = time.perf_counter()
        slow(P)
        s_all.append(time.perf_counter() - t)
        f_all.extend(f)
        ratios.append(s_all[-1] / statistics.median(f))
    return (round(statistics.median(f_all) * 1e3, 2), round(statistics.median(s_all) * 1e3, 1),
            round(statistics.median(ratios), 1))


def bench_team_step(rounds: int, per_round: int, say) -> dict:
    world = load_world(resolve_world_path(WORLD))
    domain = world_domain(world, world.robot_spec(0).radius)
    starts = np.array([[s.x, s.y] for s in world.starts])
    team = EuclideanTeam(domain)
    out: dict = {"world": WORLD, "robots": len(starts),
                 "grid": [domain.shape[1], domain.shape[0]]}
    runs, walls = {}, {}
    for solver in ("lloyd", "accelerated"):
        t0 = time.perf_counter()
        runs[solver] = solve_lloyd(team, starts, solver=solver, tolerance=0.005, max_steps=2000)
        walls[solver] = time.perf_counter() - t0
    ref_H = runs["lloyd"].cost
    for name, solver in (("plain", "lloyd"), ("accelerated", "accelerated")):
        r = runs[solver]
        out[name] = {"steps": r.steps, "converged": r.converged, "H": round(r.cost, 4),
                     "steps_within_0.1%_of_plain_H": r.steps_within(ref_H),
                     "wall_time_s": round(walls[solver], 3)}
        say(f"  {name} Lloyd: {r.steps} steps, H {r.cost:.5g}, within 0.1 % of the plain H after "
            f"{r.steps_within(ref_H)} steps, {walls[solver]:.2f} s")
    path = runs["lloyd"].positions
    # The robots' own updates compute what the team step does (cell and control): without the
    # closet escape, which once a robot settles also prices moves into its neighbours' cells.
    plain = strategy_choice("geodesic", {"escape": False})
    robots = [make_strategy(plain, StrategyContext(domain=domain, robot_id=i))
              for i in range(len(starts))]
    geo_team = GeodesicTeam(domain)
    drift = itertools.count(1)
    for kind, fast, slow, per in (
            ("lloyd", team.step, lambda P: _robots_step(domain, P), per_round),
            # a new shared search every time: the robots drift between steps
            ("geodesic", lambda P: geo_team.step(P + 1e-3 * next(drift)),
             lambda P: _geodesic_step(robots, P), max(per_round // 2, 1))):
        f_ms, s_ms, ratio = _interleaved(path, rounds, per, fast, slow)
        out[f"{kind}_ms"], out[f"{kind}_robots_ms"], out[f"{kind}_speedup"] = f_ms, s_ms, ratio
        say(f"  {kind} team step {f_ms} ms (8 decentralized updates {s_ms} ms, {ratio}x)")
    for name, solver in (("geodesic_plain", "lloyd"), ("geodesic_accelerated", "accelerated")):
        t0 = time.perf_counter()
        r = solve_lloyd(geo_team, starts, solver=solver, tolerance=0.005, max_steps=2000)
        out[name] = {"steps": r.steps, "converged": r.converged, "H": round(r.cost, 4),
                     "wall_time_s": round(time.perf_counter() - t0, 3)}
        say(f"  {name.replace('_', ' ')}: {r.steps} steps, H {r.cost:.5g}, "
            f"{out[name]['wall_time_s']:.1f} s")
    return out
