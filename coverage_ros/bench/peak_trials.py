"""The evaluation of Wang et al. (2024, Sec. V-B, Table I): time-stepped team trials towards the
peaks of an importance density, and their metrics.

* **Coverage ratio** - detected density peaks / all peaks (a peak is detected once a robot has
  it within ``detect_radius`` - its sensing range - and in line of sight);
* **Success rate** - the fraction of trials without any collision in which, within the time
  limit, either every peak was detected or every robot converged at the targets (within
  ``arrive_radius`` of a peak, in sight) - not deadlocked somewhere else. As in the paper, a
  team that converges with two robots at one peak succeeds but lowers the coverage ratio
  (their Table I: 27/30 coverage, 96.67 % success);
* **Average time** - the time until the trial ended (all peaks detected, or every robot
  converged), over the successful trials.

:func:`run_trial` executes a team the way the paper's simulation does: every robot updates its
strategy from a simulated lidar scan and its neighbours' positions each ``dt``, then all move
at once as single integrators towards their decision's goal, at no more than the strategy's
speed cap ``u_max`` (else the robot's ``v_max``) - Eq. 3 integrated over ``dt``. Collisions are
judged against the *exact* obstacle geometry of the world (:func:`world_clearance`), not the
grid the lidar is simulated on. It runs registered strategies and, through a
:data:`StrategyFactory`, methods outside the registry (the baselines of
:mod:`coverage_ros.core.baselines`), and records the CPU time of every strategy update.
:func:`cluttered_trial` draws the paper's random scenario: a cluttered arena (boxes and discs,
or discs only), a three-peak Gaussian importance density and random collision-free starts.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geometry import distance_to_segments
from coverage_ros.core.offline.rangesim import simulate_scan
from coverage_ros.core.strategies import (
    Neighbour,
    Observation,
    SharedState,
    Strategy,
    StrategyChoice,
    StrategyContext,
    make_strategy,
)
from coverage_ros.core.world import WorldSpec, parse_world
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.robot import TB3_RADIUS
from coverage_ros.errors import ConfigError

#: Collision checks per move (a robot moves at most a few cm per step; 4 samples along the
#: segment resolve a 1 cm-thick obstacle at 0.25 m steps).
MOVE_SAMPLES = 4
#: [m] tolerance of the collision test: the robot disc may not overlap an obstacle by more than
#: this (floating-point slack only).
COLLISION_TOLERANCE = 1e-6
#: [m] peaks keep this distance from obstacles, so a robot can get near them.
PEAK_CLEARANCE = 0.5

#: Builds one robot's strategy from its context: for methods outside the strategy registry
#: (the baselines of :mod:`coverage_ros.core.baselines`), e.g.
#: ``lambda ctx: OavcStrategy(ctx, obstacles=circles)``.
StrategyFactory = Callable[[StrategyContext], Strategy]


@dataclass(frozen=True)
class TrialOutcome:
    """The result of one trial."""

    detected_at: np.ndarray  # (K,) [s] first detection of each peak (inf = never)
    collided: bool  # some robot overlapped an obstacle or another robot
    converged: bool  # every robot reported convergence before the time limit
    at_targets: bool  # at the end, every robot was within arrive_radius of a peak (in sight)
    duration: float  # [s] simulated time until the trial ended
    min_clearance: float  # [m] smallest robot-obstacle gap minus the robot radius
    min_separation: float  # [m] smallest robot-robot gap minus the two radii
    positions: np.ndarray  # (T + 1, n, 2) [m] trajectories
    #: [s] CPU time of each strategy update (every robot, every step; the simulated scan
    #: excluded): what one robot computes per control period. Process time, not wall time, so
    #: that other load on a shared machine does not count.
    update_times: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def detected(self) -> np.ndarray:
        return np.isfinite(self.detected_at)

    @property
    def deadlocked(self) -> bool:
        """Neither every peak found nor every robot settled at a peak."""
        return not (bool(self.detected.all()) or (self.converged and self.at_targets))

    @property
    def success(self) -> bool:
        return not self.collided and not self.deadlocked


@dataclass(frozen=True)
class TableRow:
    """One row of the paper's Table I over a set of trials."""

    coverage_ratio: float  # detected peaks / all peaks, summed over the trials
    all_peaks: int  # trials in which every peak was detected
    trials: int
    success_rate: float  # in [0, 1]
    average_time: float  # [s] over successful trials (nan if none)
    collisions: int  # trials with a collision


def coverage_ratio(outcomes: Sequence[TrialOutcome]) -> float:
    """Detected peaks / all peaks over the trials."""
    found = sum(int(o.detected.sum()) for o in outcomes)
    total = sum(len(o.detected_at) for o in outcomes)
    return found / total if total else 0.0


def success_rate(outcomes: Sequence[TrialOutcome]) -> float:
    return sum(o.success for o in outcomes) / len(outcomes) if outcomes else 0.0


def average_time(outcomes: Sequence[TrialOutcome]) -> float:
    """[s] mean trial duration over the successful trials (nan if none)."""
    times = [o.duration for o in outcomes if o.success]
    return float(np.mean(times)) if times else math.nan


def table_row(outcomes: Sequence[TrialOutcome]) -> TableRow:
    return TableRow(coverage_ratio(outcomes), sum(bool(o.detected.all()) for o in outcomes),
                    len(outcomes), success_rate(outcomes), average_time(outcomes),
                    sum(o.collided for o in outcomes))


def line_of_sight(grid: GridMap, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the segment ``a -> b`` [m] crosses no occupied cell (sampled at a third of a
    cell)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    n = max(int(math.ceil(3.0 * float(np.hypot(*(b - a))) / grid.resolution)), 1)
    pts = a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)
    cells = grid.world_to_cell(pts)
    inside = grid.contains_cell(cells)
    if not inside.all():
        return False
    return not bool(grid.occupied_mask()[cells[:, 0], cells[:, 1]].any())


def peaks_detected(grid: GridMap, peaks: np.ndarray, positions: np.ndarray,
                   radius: float) -> np.ndarray:
    """``(K,) bool``: peaks within ``radius`` [m] of some robot and in its line of sight."""
    peaks = np.asarray(peaks, np.float64).reshape(-1, 2)
    pos = np.asarray(positions, np.float64).reshape(-1, 2)
    out = np.zeros(len(peaks), dtype=bool)
    for k, q in enumerate(peaks):
        for p in pos[np.hypot(*(pos - q).T) <= radius]:
            if line_of_sight(grid, p, q):
                out[k] = True
                break
    return out


def world_clearance(spec: WorldSpec) -> Callable[[np.ndarray], np.ndarray]:
    """A function ``(N, 2) -> (N,)`` [m]: distance from points to the nearest obstacle or arena
    wall of ``spec`` (exact geometry; 0 inside). Worlds on a map_server map are not supported."""
    if spec.base_map is not None:
        raise ConfigError.at("world.map", "exact clearance needs a world without a base map",
                             spec.source)
    circles = [o for o in spec.obstacles if o.polygon is None]
    centres = np.array([o.center for o in circles], dtype=np.float64).reshape(-1, 2)
    radii = np.array([o.radius for o in circles], dtype=np.float64)
    polys = [np.asarray(o.polygon, np.float64) for o in spec.obstacles if o.polygon is not None]
    a = np.vstack(polys) if polys else np.zeros((0, 2))
    b = np.vstack([np.roll(q, -1, axis=0) for q in polys]) if polys else np.zeros((0, 2))
    starts = np.cumsum([0] + [len(q) for q in polys])[:-1]

    def clearance(points: np.ndarray) -> np.ndarray:
        pts = np.asarray(points, np.float64).reshape(-1, 2)
        best = np.full(len(pts), np.inf)
        if spec.bounds is not None:
            xmin, ymin, xmax, ymax = spec.bounds
            best = np.minimum.reduce([best, pts[:, 0] - xmin, xmax - pts[:, 0],
                                      pts[:, 1] - ymin, ymax - pts[:, 1]])
        if len(radii):
            d = np.hypot(pts[:, None, 0] - centres[None, :, 0],
                         pts[:, None, 1] - centres[None, :, 1])
            best = np.minimum(best, (d - radii[None, :]).min(axis=1))
        if len(a):
            best = np.minimum(best, distance_to_segments(pts, a, b))
            # Even-odd rule per polygon (edges of one polygon are contiguous).
            x, y = pts[:, 0:1], pts[:, 1:2]
            straddles = (a[None, :, 1] > y) != (b[None, :, 1] > y)
            with np.errstate(divide="ignore", invalid="ignore"):
                x_cross = a[None, :, 0] + (y - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) \
                    / (b[None, :, 1] - a[None, :, 1])
            crossings = (straddles & (x < x_cross)).astype(np.int64)
            inside = (np.add.reduceat(crossings, starts, axis=1) % 2).any(axis=1)
            best[inside] = 0.0
        return np.maximum(best, 0.0)

    return clearance


def run_trial(domain: CoverageDomain, clearance: Callable[[np.ndarray], np.ndarray],
              starts: np.ndarray, peaks: np.ndarray, contexts: list[StrategyContext],
              strategy: StrategyChoice | str | StrategyFactory = "bvc", dt: float = 0.2,
              time_limit: float = 30.0, detect_radius: float = 3.5,
              arrive_radius: float = 1.0, stop_when_detected: bool = True) -> TrialOutcome:
    """Run a team from ``starts (n, 2 or 3)`` until every peak of ``peaks (K, 2)`` is detected
    (unless ``stop_when_detected`` is False: a coverage run to convergence), every robot
    reports convergence, or ``time_limit`` [s] passes. ``strategy`` is a registered strategy
    (a name or a :class:`StrategyChoice`) or a :data:`StrategyFactory`, for methods outside
    the registry."""
    if not (dt > 0 and time_limit > 0 and detect_radius > 0 and arrive_radius > 0):
        raise ConfigError.at("trial", "dt, time_limit, detect_radius and arrive_radius must "
                             "be > 0", (dt, time_limit, detect_radius, arrive_radius))
    starts = np.asarray(starts, np.float64)
    n = len(starts)
    grid = domain.geometry
    blocked = grid.occupied_mask()
    robots = [strategy(c) if callable(strategy) else make_strategy(strategy, c)
              for c in contexts]
    radii = np.array([c.robot.radius for c in contexts])
    speed = np.array([float(getattr(r, "u_max", c.robot.v_max))
                      for r, c in zip(robots, contexts, strict=True)])
    pos = starts[:, :2].copy()
    yaw = starts[:, 2].copy() if starts.shape[1] > 2 else np.zeros(n)
    peaks = np.asarray(peaks, np.float64).reshape(-1, 2)
    detected_at = np.full(len(peaks), np.inf)
    trajectory = [pos.copy()]
    min_clear = float((clearance(pos) - radii).min())
    min_sep = _min_separation(pos, radii)
    converged = False
    spent: list[float] = []
    t = 0.0
    for it in range(int(math.ceil(time_limit / dt)) + 1):
        t = it * dt
        fresh = ~np.isfinite(detected_at)
        if fresh.any():
            hit = peaks_detected(grid, peaks[fresh], pos, detect_radius)
            detected_at[np.flatnonzero(fresh)[hit]] = t
        if (stop_when_detected and np.isfinite(detected_at).all()) or t >= time_limit:
            break
        shared = [SharedState(position=pos[i].copy(), weight=contexts[i].weight,
                              extra={"radius": float(radii[i])}) for i in range(n)]
        targets = pos.copy()
        done = []
        for i, robot in enumerate(robots):
            pose = np.array([pos[i, 0], pos[i, 1], yaw[i]])
            rest = np.delete(np.arange(n), i)
            scan = simulate_scan(grid, pose, contexts[i].robot.lidar, pos[rest], radii[rest],
                                 blocked) if robot.needs_scan else None
            nbrs = [Neighbour(int(j), shared[j]) for j in rest]
            t0 = time.process_time()
            d = robot.update(Observation(i, pose, t, scan), nbrs)
            spent.append(time.process_time() - t0)
            done.append(d.converged)
            # The point the method heads for (bvc: the centroid of Eq. 3; its navigation goal
            # may lie a little beyond it, for a robot's tracker that parks short of goals).
            if d.target is not None:
                targets[i] = d.target
        step = targets - pos
        length = np.hypot(step[:, 0], step[:, 1])
        scale = np.minimum(1.0, speed * dt / np.maximum(length, 1e-12))
        new = pos + step * scale[:, None]
        moving = length > 1e-12
        yaw[moving] = np.arctan2(step[moving, 1], step[moving, 0])
        for s in np.linspace(0.0, 1.0, MOVE_SAMPLES + 1)[1:]:
            q = pos + s * (new - pos)
            min_clear = min(min_clear, float((clearance(q) - radii).min()))
            min_sep = min(min_sep, _min_separation(q, radii))
        pos = new
        trajectory.append(pos.copy())
        if all(done):
            converged, t = True, t + dt
            break
    collided = min_clear < -COLLISION_TOLERANCE or min_sep < -COLLISION_TOLERANCE
    at_targets = all(peaks_detected(grid, peaks, p, arrive_radius).any() for p in pos)
    return TrialOutcome(detected_at, collided, converged, at_targets, t, min_clear, min_sep,
                        np.array(trajectory), np.array(spent))


def _min_separation(pos: np.ndarray, radii: np.ndarray) -> float:
    if len(pos) < 2:
        return math.inf
    d = np.hypot(pos[:, None, 0] - pos[None, :, 0], pos[:, None, 1] - pos[None, :, 1])
    gap = d - (radii[:, None] + radii[None, :])
    return float(gap[np.triu_indices(len(pos), 1)].min())


@dataclass(frozen=True)
class TrialSetup:
    """One random scenario of :func:`cluttered_trial`."""

    world: WorldSpec
    domain: CoverageDomain
    starts: np.ndarray  # (n, 3) [m, m, rad]
    peaks: np.ndarray  # (K, 2) [m]


def cluttered_trial(rng: np.random.Generator, size: float = 10.0, obstacles: int = 12,
                    robots: int = 3, peaks: int = 3, sigma: float = 1.0,
                    peak_spacing: float = 3.0, resolution: float = 0.1,
                    robot_radius: float = TB3_RADIUS, start_clearance: float = 0.3,
                    circle_share: float = 0.5,
                    circle_radius: tuple[float, float] = (0.2, 0.6),
                    start_spacing: float | None = None) -> TrialSetup:
    """A ``size x size`` [m] arena with ``obstacles`` random boxes and discs (a disc with
    probability ``circle_share``, of a radius drawn from ``circle_radius`` [m]), a Gaussian
    mixture of ``peaks`` peaks (spread ``sigma`` [m], ``peak_spacing`` [m] apart) in free
    space, and ``robots`` random starts at least ``start_clearance`` [m] from every obstacle and
    ``start_spacing`` [m] apart (None: ``4 r``)."""
    if size <= 4 * start_clearance or obstacles < 0 or robots < 1 or peaks < 1:
        raise ConfigError.at("cluttered_trial", "need size > 4 start_clearance, obstacles >= 0,"
                             " robots >= 1, peaks >= 1", (size, obstacles, robots, peaks))
    if not (0.0 <= circle_share <= 1.0 and 0.0 < circle_radius[0] <= circle_radius[1]):
        raise ConfigError.at("cluttered_trial", "need 0 <= circle_share <= 1 and "
                             "0 < circle_radius[0] <= circle_radius[1]",
                             (circle_share, circle_radius))
    items = []
    for _ in range(obstacles):
        c = rng.uniform(1.0, size - 1.0, 2).round(3).tolist()
        if rng.random() < circle_share:
            items.append({"type": "circle", "center": c,
                          "radius": round(float(rng.uniform(*circle_radius)), 3)})
        else:
            items.append({"type": "box", "center": c,
                          "size": rng.uniform(0.3, 1.8, 2).round(3).tolist(),
                          "yaw": round(float(rng.uniform(0.0, math.pi)), 3)})
    base = {"name": "cluttered", "resolution": resolution, "bounds": [0.0, 0.0, size, size],
            "obstacles": items}
    spec = parse_world(base)
    clear = world_clearance(spec)
    peak_xy = _free_points(rng, clear, size, peaks, peak_spacing, PEAK_CLEARANCE)
    density = {"type": "gaussian_mixture", "components": [
        {"mean": q.round(3).tolist(), "sigma": sigma} for q in peak_xy]}
    spec = parse_world({**base, "density": density})
    spacing = 4.0 * robot_radius if start_spacing is None else start_spacing
    starts = _free_points(rng, clear, size, robots, spacing, start_clearance)
    domain = CoverageDomain.from_grid(spec.grid, robot_radius, spec.density)
    yaw = rng.uniform(-math.pi, math.pi, (robots, 1))
    return TrialSetup(spec, domain, np.hstack([starts, yaw]), peak_xy)


def _free_points(rng: np.random.Generator, clearance: Callable[[np.ndarray], np.ndarray],
                 size: float, count: int, spacing: float, margin: float) -> np.ndarray:
    """``count`` random points at least ``margin`` from obstacles and ``spacing`` apart."""
    out: list[np.ndarray] = []
    for _ in range(1000 * count):
        q = rng.uniform(0.0, size, 2)
        if clearance(q)[0] < margin:
            continue
        if all(np.hypot(*(q - o)) >= spacing for o in out):
            out.append(q)
            if len(out) == count:
                return np.array(out)
    raise ConfigError.at("cluttered_trial", "could not place the points; fewer obstacles?",
                         count)
