"""Offline exploration of an unknown map: the robots' own controllers on a simple simulator.

Each robot runs the same :class:`~coverage_ros.core.control.controller.RobotController` as a
live robot node - strategy, path planning on its belief, pure-pursuit tracking within its speed
and acceleration limits, the safety filter - and the time is stepped as a live team's would be:

* every ``step`` seconds each robot's command is integrated as a unicycle (a move that would
  put its body into a truly occupied cell or into another robot is refused and counted);
* at its lidar's rate each robot takes a scan of the true map, with the other robots as discs
  (:func:`~coverage_ros.core.offline.rangesim.simulate_scan`), and adds it to the belief;
* every ``control_period`` seconds every robot updates its strategy, having heard every other
  robot's state from the previous period.

The team shares one belief: perfect, instant exchange of evidence, which the live robots
approach over their topics (the fusion is exact either way; only the delay differs). The sim
time of a run is therefore comparable with a live run's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from coverage_ros.core.control.controller import ControllerConfig, RobotController
from coverage_ros.core.exploration.belief import Belief, BeliefSnapshot
from coverage_ros.core.exploration.scoring import ExplorationScorer, milestones
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.offline.rangesim import simulate_scan
from coverage_ros.core.strategies import StrategyChoice
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.errors import ConfigError

#: Source id of the team's shared evidence.
TEAM_SOURCE = 0


@dataclass(frozen=True)
class ExplorationConfig:
    duration: float = 900.0  # [s] sim time at most
    until_explored: float | None = None  # stop once the explored fraction reaches this
    settle: bool = True  # after exploring, run until the team has converged (or duration)
    control_period: float = 0.5  # [s] strategy updates (robot_node's control_rate 2 Hz)
    step: float = 0.1  # [s] motion integration and tracking (robot_node's tracking_rate)
    sample_period: float = 1.0  # [s] between explored-fraction samples
    settle_window: float = 10.0  # [s] settled: no robot moved more than settle_distance in it
    settle_distance: float = 0.1  # [m]

    def __post_init__(self) -> None:
        for name in ("duration", "control_period", "step", "sample_period"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError.at(name, "must be a number > 0 [s]", v)
        if self.until_explored is not None and not 0 < self.until_explored <= 1:
            raise ConfigError.at("until_explored", "must be a fraction in (0, 1]",
                                 self.until_explored)


@dataclass
class ExplorationRun:
    times: np.ndarray  # (T,) [s] sample times
    explored: np.ndarray  # (T,) explored fraction
    false_free: np.ndarray  # (T,)
    positions: np.ndarray  # (T, n, 2) [m] at the sample times
    modes: list[list[str]]  # (T, n) each robot's mode at the sample times
    paths: list[np.ndarray]  # n x (K, 2) [m] every position each robot passed
    snapshot: BeliefSnapshot  # the team's final belief
    sim_time: float  # [s]
    collisions: int  # refused moves (into a truly occupied cell or another robot)
    min_separation: float  # [m] smallest distance between two robot centres
    converged: bool  # settled: no robot moved more than settle_distance in settle_window
    explored_at: dict[str, float | None] = field(default_factory=dict)
    update_seconds: list[float] = field(default_factory=list)


def run_exploration(truth: GridMap, choice: StrategyChoice, starts: np.ndarray,
                    specs: Sequence[RobotSpec], config: ExplorationConfig | None = None,
                    connectivity: int = 8,
                    progress: Callable[[float, float], None] | None = None,
                    held: Sequence[int] = ()) -> ExplorationRun:
    """Explore ``truth`` (known only to the simulator) with robots ``specs`` from ``starts``
    ``(n, 3)``, strategy ``choice`` (an exploring one); see module docstring. The robots in
    ``held`` are driven by a person who keeps them where they start (manual, no teleop
    command): they map and publish their state like the others, which cover around them
    (Bhattacharya et al., Fig. 19)."""
    config = config or ExplorationConfig()
    if not choice.explore:
        raise ConfigError.at("strategy", "is not an exploring strategy", choice.name,
                             "geodesic or frontier with explore")
    starts = np.asarray(starts, dtype=np.float64)
    n = len(starts)
    if len(specs) != n:
        raise ConfigError.at("specs", f"gives {len(specs)} robots for {n} starts", len(specs))
    unknown = GridMap(np.full(truth.shape, -1, np.int8), truth.resolution, truth.origin)
    belief = Belief(unknown, TEAM_SOURCE)
    robots = []
    for i, spec in enumerate(specs):
        bounds = CoverageDomain.from_grid(unknown, spec.radius, connectivity=connectivity,
                                          unknown_is_free=True)
        ctrl = RobotController(bounds, ControllerConfig(robot_id=i, strategy=choice, robot=spec),
                               belief)
        ctrl.set_pose(tuple(starts[i]))
        ctrl.set_manual(i in held)
        robots.append(ctrl)
    radii = np.array([s.radius for s in specs])
    clearance = truth.clearance()
    blocked = truth.occupied_mask()
    scorer = ExplorationScorer(truth, starts, float(radii.max()))
    poses = starts.copy()
    next_scan = np.zeros(n)
    paths: list[list[np.ndarray]] = [[p[:2].copy()] for p in poses]
    times, explored, wrong, positions, modes = [], [], [], [], []
    update_seconds: list[float] = []
    collisions, min_sep, t = 0, math.inf, 0.0
    settled = False
    next_control = next_sample = 0.0
    steps = int(round(config.duration / config.step))
    for k in range(steps + 1):
        t = k * config.step
        # 1. Poses (odometry) and the scans due now.
        for i, ctrl in enumerate(robots):
            ctrl.set_pose(tuple(poses[i]))
            if t + 1e-9 >= next_scan[i]:
                next_scan[i] = t + 1.0 / specs[i].lidar.rate_hz
                others = np.delete(np.arange(n), i)
                scan = simulate_scan(truth, poses[i], specs[i].lidar, poses[others, :2],
                                     radii[others], blocked)
                ctrl.set_scan(scan, scan.points(poses[i]), poses[i])
                ctrl.integrate_scan(scan, poses[i], t)
        # 2. Coverage updates: everyone hears everyone's last state, then all update.
        if t + 1e-9 >= next_control:
            next_control = t + config.control_period
            states = [(c.last.state if c.last is not None else c.presence_state()) | {
                "x": float(poses[i, 0]), "y": float(poses[i, 1])}
                for i, c in enumerate(robots)]
            for i, ctrl in enumerate(robots):
                for j in range(n):
                    if j != i:
                        ctrl.neighbours.receive(j, states[j], t)
                result = ctrl.update(t)
                if result is not None:
                    update_seconds.append(result.state["update_ms"] * 1e-3)
        # 3. Samples.
        if t + 1e-9 >= next_sample:
            next_sample = t + config.sample_period
            score = scorer.score(belief.snapshot())
            times.append(t)
            explored.append(score.explored_fraction)
            wrong.append(score.false_free)
            positions.append(poses[:, :2].copy())
            modes.append([c.last.decision.mode if c.last is not None else "" for c in robots])
            if progress is not None:
                progress(t, score.explored_fraction)
            settled = _settled(times, positions, config)
            done = explored[-1] >= (config.until_explored or 2.0)
            fully = explored[-1] >= 0.999 or all(
                c.last is not None and c.last.decision.converged
                for i, c in enumerate(robots) if i not in held)
            if done or (fully and (not config.settle or settled)):
                break
        # 4. Motion.
        for i, ctrl in enumerate(robots):
            v, w = ctrl.command(t, config.step)
            moved, hit = _move(poses, i, v, w, config.step, radii, clearance, truth)
            collisions += hit
            if moved:
                paths[i].append(poses[i, :2].copy())
        if n > 1:
            d = np.hypot(poses[:, None, 0] - poses[None, :, 0],
                         poses[:, None, 1] - poses[None, :, 1])
            np.fill_diagonal(d, np.inf)
            min_sep = min(min_sep, float(d.min()))
    times_a = np.array(times)
    return ExplorationRun(
        times=times_a, explored=np.array(explored), false_free=np.array(wrong),
        positions=np.array(positions), modes=modes, paths=[np.array(p) for p in paths],
        snapshot=belief.snapshot(), sim_time=t, collisions=collisions, min_separation=min_sep,
        converged=settled, explored_at=milestones(times_a, explored),
        update_seconds=update_seconds)


def _settled(times: list[float], positions: list[np.ndarray], config: ExplorationConfig) -> bool:
    """Whether no robot moved more than ``settle_distance`` over the last ``settle_window``."""
    if not times or times[-1] - times[0] < config.settle_window:
        return False
    k = int(np.searchsorted(times, times[-1] - config.settle_window))
    recent = np.array(positions[k:])
    spread = np.hypot(*(recent - recent[-1]).transpose(2, 0, 1)).max()
    return bool(spread <= config.settle_distance)


def _move(poses: np.ndarray, i: int, v: float, w: float, dt: float, radii: np.ndarray,
          clearance: np.ndarray, truth: GridMap) -> tuple[bool, int]:
    """Integrate robot ``i``'s unicycle command for ``dt``; refuse a move into a truly occupied
    cell's reach or into another robot. Returns (moved, 1 if refused by a collision else 0)."""
    x, y, yaw = poses[i]
    if abs(v) < 1e-9 and abs(w) < 1e-9:
        return False, 0
    mid = yaw + 0.5 * w * dt
    new = np.array([x + v * dt * math.cos(mid), y + v * dt * math.sin(mid), yaw + w * dt])
    if abs(v) > 1e-9:
        cell = truth.world_to_cell(new[None, :2])[0]
        inside = truth.contains_cell(cell[None])[0]
        room = clearance[cell[0], cell[1]] if inside else 0.0
        others = np.delete(poses, i, axis=0)
        gaps = np.hypot(others[:, 0] - new[0], others[:, 1] - new[1]) - \
            radii[i] - np.delete(radii, i)
        if room < radii[i] or (len(gaps) and gaps.min() < 0):
            poses[i, 2] = new[2]  # the turn happens; the translation does not
            return False, 1
    poses[i] = new
    return True, 0
