"""Coverage metrics of a live team, computed with the core off the caller's thread.

The coverage cost H and the cell masses of the robots' positions come from the centralized
tessellation (:func:`coverage_ros.core.geodesic.tessellation.fast_tessellate`), as
``coverage-plan`` reports them. With visibility-based distances one tessellation takes ~0.05 s on a
12 m x 8 m office and ~0.1-0.5 s on large maps, so it runs on one worker thread: a viewer keeps
taking messages
meanwhile, and a new request while one is running is simply skipped (see :attr:`busy`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from coverage_ros.core.world.density import Density, UniformDensity
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.metric import WorldMetric, zeta_on_grid
from coverage_ros.viz.recording import CoverageRecorder

#: ``(robot_id, (x, y) [m] map frame, power weight R [m])`` of one robot.
RobotSample = tuple[int, tuple[float, float], float]


class LiveMetrics:
    """Logs ``/metrics/H`` and ``/metrics/mass/robot_<id>`` (and, on request, the
    tessellation's cells) to ``recorder`` at the sim time of each request.

    ``warn(key, text)`` reports a failed computation (e.g. a map without free space); the
    viewer carries on.
    """

    def __init__(self, recorder: CoverageRecorder, robot_radius: float,
                 density: Density | None, warn: Callable[[str, str], None],
                 metric: WorldMetric | None = None) -> None:
        self.rec = recorder
        self.robot_radius = robot_radius
        self.density = density
        self.metric = metric  # the world's travel metric (zeta), None: Euclidean
        self.warn = warn
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="metrics")
        self._job: Future | None = None
        self._domain: tuple[GridMap, object] | None = None  # owned by the worker thread

    @property
    def busy(self) -> bool:
        return self._job is not None and not self._job.done()

    def set_map(self, grid: GridMap) -> None:
        """Build the domain of a new map now (and log a non-uniform density layer)."""
        self._job = self._pool.submit(self._domain_of, grid)

    def submit(self, grid: GridMap, t: float, robots: Sequence[RobotSample],
               log_cells: Callable[[], bool] | None = None) -> bool:
        """Compute and log the metrics of ``robots`` at sim time ``t`` [s] on the worker;
        False (nothing done) while the previous request is still running. The tessellation's
        cells are logged too if ``log_cells()`` still says so when they are ready."""
        if self.busy or not robots:
            return False
        self._job = self._pool.submit(self._compute, grid, t, list(robots), log_cells)
        return True

    def close(self) -> None:
        """Wait for the running computation, drop queued ones."""
        self._pool.shutdown(wait=True, cancel_futures=True)

    # ------------------------------------------------------------------ worker thread
    def _domain_of(self, grid: GridMap):
        if self._domain is not None and self._domain[0] is grid:
            return self._domain[1]
        from coverage_ros.core.geodesic.domain import CoverageDomain

        try:
            zeta = zeta_on_grid(self.metric, grid)
            domain = CoverageDomain.from_grid(grid, self.robot_radius, self.density, zeta=zeta)
            if self.density is not None and not isinstance(self.density, UniformDensity):
                self.rec.log_density(grid, domain.density)
        except Exception as exc:  # a map the core cannot use must not end the viewer
            self.warn("domain", f"no coverage metrics for this map: {exc}")
            domain = None
        self._domain = (grid, domain)
        return domain

    def _compute(self, grid: GridMap, t: float, robots: list[RobotSample],
                 log_cells: Callable[[], bool] | None) -> None:
        from coverage_ros.core.geodesic.tessellation import Generator, fast_tessellate

        domain = self._domain_of(grid)
        if domain is None:
            return
        try:
            tess = fast_tessellate(domain, [Generator(np.array(p, dtype=np.float64), float(w))
                                            for _, p, w in robots])
        except Exception as exc:  # e.g. every robot off the map
            self.warn("metrics", f"coverage metrics at t={t:.2f} s skipped: {exc}")
            return
        ids = [r for r, _, _ in robots]
        self.rec.set_time(t)  # rerun's time is per thread
        self.rec.log_metrics(tess.cost, dict(zip(ids, tess.masses.tolist(), strict=True)))
        if log_cells is not None and log_cells():
            self.rec.log_cells(tess.labels, ids)
