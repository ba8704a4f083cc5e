"""Offline execution of a team: every robot's decentralized update, run centrally.

Each iteration, every robot computes its :class:`Decision` from the positions of all others
(as if it had heard from them all), then all robots move at once (Jacobi). A robot moves to its
goal if that does not raise the cost of its *current* cell about its new position, else it
tries half the step, and so on (``monotone``). Since the Voronoi partition of the new positions
is the best partition for them, the team's coverage cost H can then never increase - the
classic Lloyd argument, which holds exactly only if the cells really are Voronoi cells.

Strategies that steer themselves (a velocity instead of a goal) are integrated as unicycles for
``dt`` per iteration. Strategies that need a lidar get a scan simulated on the occupancy grid
(:mod:`coverage_ros.core.offline.rangesim`), in which the other robots show up as discs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from coverage_ros.core.geodesic.charts import wrap_chart_position
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.offline.rangesim import simulate_scan
from coverage_ros.core.strategies import (
    Decision,
    Neighbour,
    Observation,
    Strategy,
    StrategyChoice,
    StrategyContext,
    make_strategy,
)
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
    #: step rule: never raise the own cell's cost (strategies with ``cost_about``)
    monotone: bool = True
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


def run_offline(domain: CoverageDomain, strategy: StrategyChoice | str, starts: np.ndarray,
                contexts: list[StrategyContext] | None = None,
                config: OfflineConfig | None = None,
                progress: Callable[[int, float], None] | None = None) -> OfflineResult:
    """Run ``strategy`` (a plain name: its default settings) for robots starting at
    ``starts (n, 2 or 3)`` until convergence; ``contexts`` give each robot's spec (default: a
    TurtleBot3 each)."""
    config = config or OfflineConfig()
    starts = np.asarray(starts, dtype=np.float64)
    n = len(starts)
    if contexts is None:
        contexts = [StrategyContext(domain=domain, robot_id=i) for i in range(n)]
    robots: list[Strategy] = [make_strategy(strategy, c) for c in contexts]
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
            new[i], yaw[i] = _move(domain, robots[i], pos[i], yaw[i], d, config)
        pos = new
        positions.append(pos.copy())
        yaws.append(yaw.copy())
        moved = float(np.hypot(*(pos - positions[-2]).T).max())
        # Self-steering robots move less than the tolerance per step while under way: only
        # their own convergence counts.
        # Nobody moving counts as settled too (steps the monotone rule rejects for good),
        # unless a strategy has a phase under way that may move a robot later (``settling``:
        # e.g. an alpha-CVT dropout yet to end).
        steering = any(d.velocity is not None for d in decisions)
        still = all(d.converged for d in decisions) or (
            not steering and moved < contexts[0].convergence_tolerance
            and not any(d.settling for d in decisions))
        settled = settled + 1 if still else 0
        if progress is not None:
            progress(it, costs[-1])
        if settled >= SETTLE_ITERATIONS:
            break
    return OfflineResult(np.array(positions), np.array(yaws), np.array(costs), it,
                         settled >= SETTLE_ITERATIONS, times, decisions)


def _move(domain: CoverageDomain, robot: Strategy, p: np.ndarray, yaw: float, d: Decision,
          config: OfflineConfig) -> tuple[np.ndarray, float]:
    robot_spec = robot.context.robot
    if d.velocity is not None:
        v, w = d.velocity
        v = float(np.clip(v, -robot_spec.v_max, robot_spec.v_max))
        w = float(np.clip(w, -robot_spec.w_max, robot_spec.w_max))
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
    current = robot.cost_about(d, p) if config.monotone else None
    if current is None:
        return _wrapped(domain, goal), heading
    for _ in range(MAX_HALVINGS):
        q = _wrapped(domain, p + step)
        if domain.is_free_point(q):
            cost = robot.cost_about(d, q)
            if cost is not None and cost <= current * (1 + 1e-12) + 1e-12:
                return q, heading
        step = 0.5 * step
    return p, yaw


def _wrapped(domain: CoverageDomain, q: np.ndarray) -> np.ndarray:
    return wrap_chart_position(domain, q) if any(domain.graph.wrap) else q
