"""What a team run gives a user (pure: no ROS): the :class:`RunLog` the monitor fills, and
from it ``summary.json``, the table printed at the end and ``summary.png``.

The metrics of ``summary.json`` (definitions in README "Team launcher"):

* ``H`` / ``H_start``: geodesic coverage cost (density-weighted, as ``coverage-plan``) of the
  final / start positions of the robots still running;
* ``mass_deviation_I``: Lee & Lee's I of the final geodesic cell masses;
* ``coverage_ratio``: free area within its sensing radius and line of sight of some robot;
* ``min_separation``: smallest distance between two robot centres during the run (the
  simulator checks every physics step);
* ``converged_at``: first sim time from which H stayed within 2 % of its final value (None
  when only the last sample did);
* ``H_series``: ``[[t, H], ...]`` as the monitor sampled it (t: sim time since the team was
  ready).

In lock-step (``--lockstep``) every figure of ``summary.json`` is the same for the same command
and seed, except the wall-clock ones named in :data:`WALL_CLOCK_KEYS`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tessellation import Generator, Tessellation, fast_tessellate
from coverage_ros.core.metrics import coverage_ratio, mass_deviation
from coverage_ros.core.world import TeamMember
from coverage_ros.core.world.robot import NUMBER_FIELDS
from coverage_ros.core.world.spec import WorldSpec

CONVERGED_BAND = 0.02  # H within 2 % of its final value counts as converged
#: summary.json keys measured on the wall clock (they differ run to run, lock-step or not).
WALL_CLOCK_KEYS = ("wall_time", "rtf", "processes")


def converged_at(samples: list[tuple[float, float]], H_final: float,
                 ready_at: float | None) -> float | None:
    """First sim time [s, since ``ready_at``] from which the ``(t, H)`` samples stayed within
    CONVERGED_BAND of ``H_final``; None if there is none, or only the last sample is (H was
    still moving when the run ended)."""
    if not samples or not math.isfinite(H_final):
        return None
    t_conv = None
    for t, h in reversed(samples):
        if not abs(h - H_final) <= CONVERGED_BAND * H_final:
            break
        t_conv = t
    if t_conv is None or (len(samples) > 1 and t_conv == samples[-1][0]):
        return None
    return round(t_conv - (ready_at or 0.0), 3)


@dataclass
class RunLog:
    """What the monitor measured of a run: sim times [s], the robots' poses ``(x, y, yaw)``,
    driven paths, the world's status of each robot (SimulatedRobot's fields), losses and
    restarts, H samples ``(t, H)`` and what the run ended with."""

    sim_time: float = 0.0
    ready_at: float | None = None  # the team was up
    sim_start: float | None = None  # sim and wall time [s, monotonic] the run's rtf starts from
    wall_start: float | None = None
    run_span: tuple[float, float] | None = None  # (sim, wall) [s] from ready to the end
    poses: dict[int, np.ndarray] = field(default_factory=dict)
    tracks: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    status: dict[int, dict[str, float]] = field(default_factory=dict)
    lost: dict[int, float] = field(default_factory=dict)  # robot -> sim time lost
    restarted: dict[int, list[float]] = field(default_factory=dict)  # -> [s since ready]
    H_samples: list[tuple[float, float]] = field(default_factory=list)
    region: list[np.ndarray] = field(default_factory=list)  # polygons at the end
    region_set_at: float | None = None  # sim time
    exploration: dict | None = None
    settled_at: float | None = None  # [s since ready] the run ended settled (--until-settled)
    processes: dict | None = None

    @property
    def min_separation(self) -> float:
        return min((st.get("min_separation", math.inf) for st in self.status.values()),
                   default=math.inf)

    @property
    def collisions(self) -> int:
        return sum(int(s.get("collisions", 0)) for s in self.status.values())

    def present(self, robots: int) -> list[int]:
        """Robots not lost whose pose is known."""
        return [i for i in range(robots) if i not in self.lost and i in self.poses]


def tessellate(domain: CoverageDomain, team: Sequence[TeamMember], ids: list[int],
               positions: np.ndarray) -> Tessellation:
    """Robots ``ids`` at ``positions`` as the tessellation sees them: each with its own power
    weight."""
    return fast_tessellate(domain, [Generator(p, team[i].spec.power_weight)
                                    for i, p in zip(ids, positions, strict=True)])


def team_cost(domain: CoverageDomain, team: Sequence[TeamMember], log: RunLog) -> float:
    """H of the robots present now (nan if none)."""
    ids = log.present(len(team))
    if not ids:
        return math.nan
    return float(tessellate(domain, team, ids, np.array([log.poses[i][:2] for i in ids])).cost)


@dataclass(frozen=True)
class RobotResult:
    """One robot in ``summary.json``: start and final pose ``(x, y, yaw)``, path [m],
    collisions, its spec and role, the body the world simulated, when it was lost [s of sim
    time] and restarted [s since ready]."""

    id: int
    start: list[float]
    final: list[float] | None
    path_length: float
    collisions: int
    robot_collisions: int
    wall_collisions: int
    spec: dict[str, float]
    role: str
    body: dict[str, float]
    lost_at: float | None = None
    restarted_at: list[float] | None = None

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        for key in ("lost_at", "restarted_at"):
            if out[key] is None:
                del out[key]
        return out


@dataclass(frozen=True)
class Metrics:
    """The run's scores (module docstring); None where there was nothing to score."""

    H: float | None
    H_start: float
    mass_deviation_I: float | None  # noqa: N815 - the summary.json key, Lee & Lee's I
    coverage_ratio: float
    min_separation: float | None
    converged_at: float | None
    H_series: list[list[float]]


@dataclass(frozen=True)
class TeamSummary:
    """A run's ``summary.json``, typed: :meth:`as_dict` is the file's content."""

    world: str
    strategy: str
    seed: int
    sim_time: float
    wall_time: float
    rtf: float
    ready_at: float | None
    interrupted: bool
    robots: list[RobotResult]
    metrics: Metrics
    region_polygons: list[list[list[float]]]
    region_set_at: float | None
    processes: dict | None = None
    exploration: dict | None = None
    settled_at: float | None = None  # [s since ready] the run ended settled (--until-settled)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "world": self.world, "strategy": self.strategy, "seed": self.seed,
            "sim_time": self.sim_time, "wall_time": self.wall_time, "rtf": self.rtf,
            "ready_at": self.ready_at, "interrupted": self.interrupted,
            "robots": [r.as_dict() for r in self.robots], "metrics": asdict(self.metrics),
            "region": {"polygons": self.region_polygons, "set_at": self.region_set_at}}
        if self.processes is not None:
            out["processes"] = self.processes
        if self.exploration is not None:
            out["exploration"] = self.exploration
        if self.settled_at is not None:
            out["settled_at"] = self.settled_at
        return out


def summarize(log: RunLog, team: Sequence[TeamMember], world: WorldSpec,
              domain: CoverageDomain, strategy: str, seed: int, wall_time: float,
              interrupted: bool) -> TeamSummary:
    """The summary of a run (module docstring); ``domain``: the scoring's, with the region
    of interest in force at the end."""
    n = len(team)
    alive = log.present(n)
    P = np.array([log.poses[i][:2] for i in alive]).reshape(-1, 2)
    tess = tessellate(domain, team, alive, P) if len(P) else None
    starts = np.array([m.start for m in team], dtype=np.float64)
    H_start = float(tessellate(domain, team, list(range(n)), starts[:, :2]).cost)
    sensing = np.array([team[i].spec.sensor_radius for i in alive])
    robots = []
    for i in range(n):
        st = log.status.get(i, {})
        final = log.poses.get(i)
        robots.append(RobotResult(
            i, starts[i].round(4).tolist(), None if final is None else np.round(final, 4).tolist(),
            round(st.get("path_length", 0.0), 4), int(st.get("collisions", 0)),
            int(st.get("robot_collisions", 0)), int(st.get("wall_collisions", 0)),
            team[i].spec.numbers(), team[i].role,
            {k: float(st[k]) for k in NUMBER_FIELDS if k in st},
            round(log.lost[i], 2) if i in log.lost else None, log.restarted.get(i)))
    H = float(tess.cost) if tess is not None else math.nan
    min_sep = log.min_separation
    ready = log.ready_at or 0.0
    samples = list(log.H_samples)
    if math.isfinite(H) and samples and samples[-1][0] < log.sim_time:  # (an interrupted run)
        samples.append((log.sim_time, H))
    metrics = Metrics(
        H if math.isfinite(H) else None, H_start,
        mass_deviation(tess.masses) if tess is not None else None,
        coverage_ratio(world.grid, P, sensing),
        min_sep if math.isfinite(min_sep) else None,
        converged_at(samples, H, log.ready_at),
        [[round(t - ready, 2), round(h, 6)] for t, h in samples if math.isfinite(h)])
    return TeamSummary(
        str(world.source), strategy, seed, round(log.sim_time, 3), round(wall_time, 3),
        0.0 if log.run_span is None else round(log.run_span[0] / max(log.run_span[1], 1e-9), 3),
        None if log.ready_at is None else round(log.ready_at, 3), interrupted, robots, metrics,
        [p.round(4).tolist() for p in log.region],
        None if log.region_set_at is None or log.ready_at is None
        else round(max(log.region_set_at - log.ready_at, 0.0), 3),
        log.processes, log.exploration,
        None if log.settled_at is None else round(log.settled_at, 3))


def picture(path: Path, log: RunLog, team: Sequence[TeamMember], world: WorldSpec,
            domain: CoverageDomain, strategy: str) -> None:
    """``summary.png`` (:func:`coverage_ros.viz.png.render_team`): cells, starts, paths."""
    from coverage_ros.viz.png import render_team

    n = len(team)
    alive = log.present(n)
    P = np.array([log.poses[i][:2] for i in alive]).reshape(-1, 2)
    own = tessellate(domain, team, alive, P).labels if len(P) else None
    starts = np.array([m.start for m in team], dtype=np.float64)
    render_team(path, world.grid, own, alive, starts, [log.tracks.get(i, []) for i in range(n)],
                domain.density, f"{strategy}: {n} robots, {log.sim_time:.0f} s")


def deterministic_part(summary: dict) -> dict:
    """``summary`` without its wall-clock figures (what lock-step runs reproduce exactly)."""
    return {k: v for k, v in summary.items() if k not in WALL_CLOCK_KEYS}


def summary_table(summary: dict) -> str:
    """A short human-readable table of a summary."""
    m = summary["metrics"]

    def xy(p) -> str:
        return "-" if p is None else f"({p[0]:.2f}, {p[1]:.2f})"

    def num(v, digits: int = 3) -> str:
        return "-" if v is None else f"{v:.{digits}g}"

    lines = [f"{'robot':>5} {'start (x, y)':>16} {'final (x, y)':>16} {'path [m]':>9} "
             f"{'collisions':>10}"]
    for r in summary["robots"]:
        final = "lost" if r.get("lost_at") is not None else xy(r["final"])
        lines.append(f"{r['id']:>5} {xy(r['start']):>16} {final:>16} {r['path_length']:>9.2f} "
                     f"{r['collisions']:>10d}")
    drop = 100.0 * (1.0 - m["H"] / m["H_start"]) if m["H_start"] else math.nan
    change = f"{drop:.0f} % lower" if not drop < 0 else f"{-drop:.0f} % higher"
    conv_at = "-" if m["converged_at"] is None else f"{m['converged_at']:.1f} s"
    lines.append(f"H {num(m['H'], 4)} (start {num(m['H_start'], 4)}, {change}), "
                 f"I {num(m['mass_deviation_I'])}, coverage {100 * m['coverage_ratio']:.0f} %, "
                 f"min separation {num(m['min_separation'])} m, converged at {conv_at}")
    ex = summary.get("exploration")
    if ex is not None:
        at = ", ".join(f"{k}: {'-' if v is None else f'{v:g} s'}"
                       for k, v in ex["explored_at"].items())
        lines.append(f"explored {100 * ex['explored_fraction']:.1f} % (reached {at}); false "
                     f"free {100 * ex['false_free']:.2f} %")
    if summary.get("settled_at") is not None:
        lines.append(f"settled at {summary['settled_at']:.1f} s (--until-settled): ended "
                     "before --duration")
    lines.append(f"real-time factor {summary['rtf']:.2f} over the run; sim time "
                 f"{summary['sim_time']:.1f} s in {summary['wall_time']:.1f} s wall with start-up "
                 "and shutdown")
    return "\n".join(lines)
