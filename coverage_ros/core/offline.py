"""Offline execution of a team: every robot's decentralized update, run centrally.

Each iteration, every robot computes its :class:`Decision` from the positions of all others
(as if it had heard from them all), then all robots move at once (Jacobi). A robot moves to its
goal if that does not raise the cost of its *current* cell about its new position, else it
tries half the step, and so on (``monotone``). Since the Voronoi partition of the new positions
is the best partition for them, the team's coverage cost H can then never increase - the
classic Lloyd argument, which holds exactly only if the cells really are Voronoi cells.

Strategies that steer themselves (a velocity instead of a goal) are integrated as unicycles for
``dt`` per iteration. Strategies that need a lidar get a scan simulated on the occupancy grid
(:mod:`coverage_ros.core.rangesim`), in which the other robots show up as discs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.charts import wrap_chart_position
from coverage_ros.core.domain import CoverageDomain
from coverage_ros.core.local_search import local_graph_for
from coverage_ros.core.rangesim import simulate_scan
from coverage_ros.core.strategies import (
    Decision,
    Neighbour,
    Observation,
    Strategy,
    StrategyContext,
    make_strategy,
)
from coverage_ros.core.tessellation import resolve_method, source_row
from coverage_ros.errors import ConfigError

#: Step halvings tried before a robot stays put for an iteration.
MAX_HALVINGS = 6
#: Iterations in a row in which every robot reached its goal, or no robot moved more than the
#: convergence tolerance (all remaining steps rejected by the monotone rule), before the run
#: counts as converged.
SETTLE_ITERATIONS = 3


@dataclass(frozen=True)
class OfflineConfig:
    max_iterations: int = 300
    monotone: bool = True  # step rule: never raise the own cell's cost (geodesic, lloyd)
    dt: float = 0.2  # [s] integration step of self-steering strategies

    def __post_init__(self) -> None:
        if self.max_iterations < 1:
            raise ConfigError.at("max_iterations", "must be >= 1", self.max_iterations)
        if not self.dt > 0:
            raise ConfigError.at("dt", "must be > 0", self.dt)


@dataclass
class OfflineResult:
    positions: np.ndarray  # (T + 1, n, 2) [m], start first
    yaws: np.ndarray  # (T + 1, n) [rad]
    costs: np.ndarray  # (T,) sum of own-cell costs at the start of each iteration
    iterations: int
    converged: bool
    update_seconds: list[float] = field(default_factory=list)  # one robot's update, each call
    decisions: list[Decision] = field(default_factory=list)  # last iteration's


def _own_geodesic_cost(domain: CoverageDomain, nodes: np.ndarray, point: np.ndarray,
                       weight: float, limit: float, method: str) -> float:
    """Cost of the fixed cell ``nodes`` about ``point`` (geodesic distances from it, with the
    same sources as the tessellation)."""
    local = local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1), math.inf)
    row = source_row(domain, local, domain.snap(point), limit, resolve_method(domain, method))
    csr = local.with_sources([row])
    d = dijkstra(csr, directed=True, indices=local.n + 1, limit=limit)
    g = d[nodes + 1]  # whole-graph local ids are node ids + 1
    if not np.all(np.isfinite(g)):
        return math.inf
    return float(((g * g - weight ** 2) * domain.mass_element.ravel()[nodes]).sum())


def _own_euclidean_cost(domain: CoverageDomain, nodes: np.ndarray, point: np.ndarray,
                        weight: float) -> float:
    xy = domain.to_map(domain.node_centers(nodes))
    f = ((xy - point) ** 2).sum(axis=1) - weight ** 2
    return float((f * domain.mass_element.ravel()[nodes]).sum())


def run_offline(domain: CoverageDomain, strategy: str, starts: np.ndarray,
                contexts: list[StrategyContext] | None = None,
                config: OfflineConfig | None = None,
                progress: Callable[[int, float], None] | None = None,
                **params) -> OfflineResult:
    """Run ``strategy`` for robots starting at ``starts (n, 2 or 3)`` until convergence."""
    config = config or OfflineConfig()
    starts = np.asarray(starts, dtype=np.float64)
    n = len(starts)
    if contexts is None:
        contexts = [StrategyContext(domain=domain, robot_id=i) for i in range(n)]
    robots: list[Strategy] = [make_strategy(strategy, c, **params) for c in contexts]
    pos = starts[:, :2].copy()
    yaw = starts[:, 2].copy() if starts.shape[1] > 2 else np.zeros(n)
    positions, yaws, costs, times = [pos.copy()], [yaw.copy()], [], []
    radii = np.array([c.robot.radius for c in contexts])
    blocked = domain.geometry.occupied_mask()
    settled = 0
    decisions: list[Decision] = []
    it = 0
    # What each robot last published (its decision's shared state; before its first update,
    # its strategy's initial state), with the position its odometry gives now.
    published = [robots[i].shared_state(Observation(i, np.array([*pos[i], yaw[i]]), 0.0))
                 for i in range(n)]
    for it in range(1, config.max_iterations + 1):
        shared = [replace(published[i], position=pos[i].copy()) for i in range(n)]
        decisions = []
        for i, robot in enumerate(robots):
            pose = np.array([pos[i, 0], pos[i, 1], yaw[i]])
            scan = None
            if robot.needs_scan:
                rest = np.delete(np.arange(n), i)
                scan = simulate_scan(domain.geometry, pose, contexts[i].robot.lidar,
                                     pos[rest], radii[rest], blocked)
            obs = Observation(i, pose, it * config.dt, scan)
            nbrs = [Neighbour(j, shared[j]) for j in range(n) if j != i]
            t0 = time.perf_counter()
            decisions.append(robot.update(obs, nbrs))
            times.append(time.perf_counter() - t0)
        costs.append(sum(d.cost for d in decisions))
        published = [d.shared for d in decisions]
        new = pos.copy()
        for i, d in enumerate(decisions):
            new[i], yaw[i] = _move(domain, strategy, contexts[i], pos[i], yaw[i], d, config)
        pos = new
        positions.append(pos.copy())
        yaws.append(yaw.copy())
        moved = float(np.hypot(*(pos - positions[-2]).T).max())
        # Self-steering robots move less than the tolerance per step while under way: only
        # their own convergence counts.
        steering = any(d.velocity is not None for d in decisions)
        still = all(d.converged for d in decisions) or (
            not steering and moved < contexts[0].convergence_tolerance)
        settled = settled + 1 if still else 0
        if progress is not None:
            progress(it, costs[-1])
        if settled >= SETTLE_ITERATIONS:
            break
    return OfflineResult(np.array(positions), np.array(yaws), np.array(costs), it,
                         settled >= SETTLE_ITERATIONS, times, decisions)


def _move(domain: CoverageDomain, strategy: str, ctx: StrategyContext, p: np.ndarray,
          yaw: float, d: Decision, config: OfflineConfig) -> tuple[np.ndarray, float]:
    if d.velocity is not None:
        v, w = d.velocity
        v = float(np.clip(v, -ctx.robot.v_max, ctx.robot.v_max))
        w = float(np.clip(w, -ctx.robot.w_max, ctx.robot.w_max))
        yaw_new = yaw + w * config.dt
        q = p + v * config.dt * np.array([math.cos(yaw + 0.5 * w * config.dt),
                                          math.sin(yaw + 0.5 * w * config.dt)])
        return (q if domain.is_free_point(q) else p), float(yaw_new)
    if d.goal is None:
        return p, yaw
    goal = np.asarray(d.goal, dtype=np.float64)
    step = goal - p
    if float(np.hypot(*step)) < 1e-12:
        return p, yaw
    heading = float(math.atan2(step[1], step[0]))
    if not config.monotone or strategy not in ("geodesic", "lloyd") or len(d.cell) == 0:
        return _wrapped(domain, goal), heading
    if strategy == "geodesic":
        radius = float(d.info.get("cell_radius", 0.0))
        edge = domain.graph.max_edge_cost
        bound = 1.1 * float(np.hypot(*step)) / max(domain.metric_lower_bound, 1e-9)

        def cost(q: np.ndarray) -> float:
            return _own_geodesic_cost(domain, d.cell, q, ctx.weight, radius + bound + 4 * edge,
                                      str(d.info.get("method", "auto")))
    else:
        def cost(q: np.ndarray) -> float:
            return _own_euclidean_cost(domain, d.cell, q, ctx.weight)
    current = cost(p)
    for _ in range(MAX_HALVINGS):
        q = _wrapped(domain, p + step)
        if domain.is_free_point(q) and cost(q) <= current * (1 + 1e-12) + 1e-12:
            return q, heading
        step = 0.5 * step
    return p, yaw


def _wrapped(domain: CoverageDomain, q: np.ndarray) -> np.ndarray:
    return wrap_chart_position(domain, q) if any(domain.graph.wrap) else q
