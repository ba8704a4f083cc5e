"""A live team's rerun layers: what arrives per robot, logged at sim-time rates (no ROS).

:class:`LiveTeam` receives already converted data (numpy, ``map`` frame, sim time [s]) from a
transport front end - the ROS node :mod:`coverage_ros.nodes.rerun_bridge`, or a test - and
writes it to a :class:`~coverage_ros.viz.recording.CoverageRecorder`:

* poses update the robot markers every ``robots_period`` and each robot's trajectory every
  ``trajectory_period``; a scan is placed with the pose at its own stamp (interpolated);
* the robots' cropped cells are composed into one label grid every ``cells_period`` when one
  changed; until the first cell arrives, the metrics' tessellation can stand in for them;
* every ``metrics_period`` the coverage cost H and the cell masses of the current positions
  are computed by :class:`~coverage_ros.viz.live_metrics.LiveMetrics` on its worker thread.

Robots join with :meth:`add_robot` and leave with :meth:`remove_robot` (their scan, plan and
outline disappear; the driven trajectory stays).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from coverage_ros.core.control.pose_history import TIME_JUMP_BACK, PoseHistory
from coverage_ros.core.exploration.belief import Evidence
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.robot import TB3_RADIUS
from coverage_ros.viz.live_exploration import ExplorationLayer
from coverage_ros.viz.live_metrics import LiveMetrics
from coverage_ros.viz.recording import CoverageRecorder
from coverage_ros.viz.team import Schedule, Trajectory, compose_cell_labels

TRAJECTORY_SEGMENT = 100  # [points] trajectory piece size (see viz.team.Trajectory)
# Scans newer than the robot's latest pose wait for the pose at their stamp (poses and scans
# travel on separate topics, so a scan may overtake the pose of its own time step); at most
# this many per robot, then the oldest is placed with the nearest pose known.
MAX_PENDING_SCANS = 4

Pose = tuple[float, float, float]  # (x [m], y [m], yaw [rad]) in the map frame


@dataclass(frozen=True)
class LiveRates:
    """Sim-time periods [s] of the layers (0: every message) and drawing settings."""

    robots_period: float = 0.1
    trajectory_period: float = 0.5
    scan_period: float = 0.5
    cells_period: float = 0.5
    metrics_period: float = 1.0  # 0: no metrics
    scan_decimation: int = 2  # log every n-th lidar hit
    robot_radius: float = TB3_RADIUS  # [m] marker size
    computed_cells: bool = True  # the tessellation's cells until a robot publishes one


@dataclass
class RobotLayers:
    """What is known about one robot."""

    robot_id: int
    trajectory_due: Schedule
    scan_due: Schedule
    poses: PoseHistory = field(default_factory=PoseHistory)
    goal: tuple[float, float] | None = None
    cell: GridMap | None = None
    cell_order: int = 0  # newer cells win where cells overlap
    weight: float = 0.0  # power weight R [m] from the robot's coverage state
    pending_scans: list = field(default_factory=list)  # [(t, to_map)] waiting for a pose


class LiveTeam:
    """See module docstring. Call every method from one thread (the metrics worker is
    internal); ``t`` arguments are sim times [s] of the data."""

    def __init__(self, recorder: CoverageRecorder, rates: LiveRates,
                 metrics: LiveMetrics | None = None) -> None:
        self.rec = recorder
        self.rates = rates
        self.metrics = metrics
        self.robots: dict[int, RobotLayers] = {}
        self.trajectories: dict[int, Trajectory] = {}  # kept when a robot leaves and returns
        self.grid: GridMap | None = None
        self.now = 0.0  # [s] latest sim time seen
        self._robots_due = Schedule(rates.robots_period)
        self._cells_due = Schedule(rates.cells_period)
        self._metrics_due = Schedule(rates.metrics_period)
        self._cells_dirty = False
        self._cell_count = 0  # cells received so far
        #: Exploring: the team's merged belief, logged over time (set by the front end).
        self.exploration: ExplorationLayer | None = None

    # ------------------------------------------------------------------ time and map
    def advance(self, t: float) -> None:
        """The clock says ``t``: run what is due."""
        self.now = t if t < self.now - TIME_JUMP_BACK else max(self.now, t)
        self.tick()

    def seen(self, t: float) -> float:
        """Note a data stamp ``t`` (0: unset, meaning now); returns the time to log it at."""
        if t <= 0.0:
            return self.now
        self.now = max(self.now, t)
        return t

    def set_map(self, grid: GridMap) -> bool:
        """A map arrived; False when it is the one already shown."""
        old = self.grid
        if (old is not None and old.shape == grid.shape and old.origin == grid.origin
                and old.resolution == grid.resolution
                and np.array_equal(old.occupancy, grid.occupancy)):
            return False
        self.grid = grid
        self.rec.log_map(grid)
        self.rec.send_blueprint()  # now the view can look at the map from above
        self._cells_dirty = True
        if self.metrics is not None:
            self.metrics.set_map(grid)
        return True

    # ------------------------------------------------------------------ robots
    def add_robot(self, robot_id: int) -> None:
        r = self.rates
        self.robots[robot_id] = RobotLayers(robot_id, Schedule(r.trajectory_period),
                                            Schedule(r.scan_period))
        self.trajectories.setdefault(robot_id, Trajectory(TRAJECTORY_SEGMENT))
        self.rec.name_series([robot_id])

    def remove_robot(self, robot_id: int) -> None:
        if self.robots.pop(robot_id, None) is None:
            return
        rec = self.rec
        rec.set_time(self.now)
        traj = self.trajectories[robot_id]
        traj.break_path()
        for k, points in traj.take_finished():
            rec.log_path("trajectories", robot_id, points, part=k)
        for kind in ("trajectories", "scans", "plans", "cell_polygons"):
            rec.clear(f"/world/{kind}/robot_{robot_id}")
        self._log_robots(self.now)
        self._log_goals(self.now)
        self._cells_dirty = True

    def pose(self, robot_id: int, t: float, pose: Pose) -> None:
        view = self.robots.get(robot_id)
        if view is None:
            return  # left while the message was in flight
        if not all(math.isfinite(v) for v in pose):
            raise ValueError(f"pose {pose} is not finite")
        t = self.seen(t)
        view.poses.add(t, pose)
        while view.pending_scans and view.pending_scans[0][0] <= t + 1e-9:
            self._place_scan(view, *view.pending_scans.pop(0))
        if self._robots_due.due(t):
            self._log_robots(t)
        traj = self.trajectories[robot_id]
        if view.trajectory_due.due(t) and traj.add(pose[0], pose[1]):
            self.rec.set_time(t)
            self.rec.log_trajectory(robot_id, traj.tail, traj.take_finished())
        self.tick()

    def scan(self, robot_id: int, t: float, to_map: Callable[[Pose], np.ndarray]) -> bool:
        """A scan taken at ``t``: ``to_map(pose)`` gives its ``(N, 2)`` hits in the map frame
        for the robot's pose at ``t``. False when no pose near ``t`` is known (dropped)."""
        view = self.robots.get(robot_id)
        t = self.seen(t)
        if view is None or not view.scan_due.due(t):
            return True
        latest = view.poses.latest_time
        if latest is None or latest >= t - 1e-9:
            return self._place_scan(view, t, to_map)
        view.pending_scans.append((t, to_map))  # its pose is probably on the way
        if len(view.pending_scans) > MAX_PENDING_SCANS:
            return self._place_scan(view, *view.pending_scans.pop(0))
        return True

    def _place_scan(self, view: RobotLayers, t: float,
                    to_map: Callable[[Pose], np.ndarray]) -> bool:
        pose = view.poses.at(t)
        if pose is None:
            return False
        self.rec.set_time(t)
        self.rec.log_scan(view.robot_id, to_map(pose)[::self.rates.scan_decimation])
        return True

    def goal(self, robot_id: int, t: float, xy: tuple[float, float]) -> None:
        view = self.robots.get(robot_id)
        if view is None:
            return
        if not all(math.isfinite(v) for v in xy):
            raise ValueError(f"goal {xy} is not finite")
        view.goal = (float(xy[0]), float(xy[1]))
        self._log_goals(self.seen(t))

    def plan(self, robot_id: int, t: float, points: np.ndarray) -> None:
        self._strip("plans", robot_id, t, points)

    def polygon(self, robot_id: int, t: float, points: np.ndarray) -> None:
        self._strip("cell_polygons", robot_id, t, points)

    def _strip(self, kind: str, robot_id: int, t: float, points: np.ndarray) -> None:
        if robot_id not in self.robots:
            return
        if not np.all(np.isfinite(points)):
            raise ValueError(f"{kind}: non-finite points")
        self.rec.set_time(self.seen(t))
        if not len(points):
            self.rec.clear(f"/world/{kind}/robot_{robot_id}")
        elif kind == "plans":
            self.rec.log_path(kind, robot_id, points)
        else:
            self.rec.log_polygon(robot_id, points)

    def cell(self, robot_id: int, t: float, cell: GridMap | None) -> None:
        """The robot's cell grid (cropped, map frame, >= 50 in the cell); None: no cell."""
        view = self.robots.get(robot_id)
        if view is None:
            return
        view.cell = cell
        self._cell_count += 1
        view.cell_order = self._cell_count
        self._cells_dirty = True
        self.seen(t)
        self.tick()

    def state(self, robot_id: int, t: float, values: dict[str, float]) -> None:
        """A robot's coverage state (time series; ``weight`` enters the metrics)."""
        view = self.robots.get(robot_id)
        if view is None:
            return
        weight = values.get("weight", 0.0)
        view.weight = weight if math.isfinite(weight) else 0.0
        self.rec.set_time(self.seen(t))
        self.rec.log_values(f"/state/robot_{robot_id}", values)

    def observations(self, robot_id: int, t: float, evidence: Evidence) -> None:
        """An exploring robot's evidence (merged into the viewer's belief)."""
        if self.exploration is not None:
            self.seen(t)
            self.exploration.evidence(evidence)

    def status(self, where: str, t: float, values: dict[str, float]) -> None:
        """Counters of the world or of a robot, as time series under ``/status/<where>``."""
        self.rec.set_time(self.seen(t))
        self.rec.log_values(f"/status/{where}", values)

    # ------------------------------------------------------------------ layers
    def _log_robots(self, t: float) -> None:
        known = [(r, v.poses.latest) for r, v in sorted(self.robots.items())
                 if v.poses.latest is not None]
        self.rec.set_time(t)
        self.rec.log_robots([r for r, _ in known],
                            np.array([p[:2] for _, p in known]).reshape(-1, 2),
                            self.rates.robot_radius)

    def _log_goals(self, t: float) -> None:
        goals = [(r, v.goal) for r, v in sorted(self.robots.items()) if v.goal is not None]
        self.rec.set_time(t)
        self.rec.log_goals([r for r, _ in goals], np.array([g for _, g in goals]).reshape(-1, 2))

    def tick(self) -> None:
        """Periodic layers at the current sim time: the composed cells and the metrics."""
        t = self.now
        if (self.grid is not None and self._cell_count and self._cells_dirty
                and self._cells_due.due(t)):
            views = sorted((v for v in self.robots.values() if v.cell is not None),
                           key=lambda v: v.cell_order)
            labels = compose_cell_labels(self.grid, [v.cell for v in views if v.cell is not None])
            self.rec.set_time(t)
            self.rec.log_cells(labels, [v.robot_id for v in views])
            self._cells_dirty = False
        if self.exploration is not None:
            self.exploration.tick(t, np.array([v.poses.latest[:2] for v in self.robots.values()
                                               if v.poses.latest is not None]).reshape(-1, 2))
        if (self.metrics is not None and self.rates.metrics_period > 0
                and self.grid is not None and not self.metrics.busy
                and self._metrics_due.due(t)):
            self.metrics.submit(self.grid, t, [
                (r, v.poses.latest[:2], v.weight) for r, v in sorted(self.robots.items())
                if v.poses.latest is not None], self._show_computed_cells)

    def _show_computed_cells(self) -> bool:
        return self.rates.computed_cells and self._cell_count == 0
