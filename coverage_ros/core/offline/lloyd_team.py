"""The whole team's Lloyd step at once, vectorized (``coverage-plan --strategy lloyd|geodesic
--solver lloyd|accelerated``); the solvers are in :mod:`coverage_ros.core.offline.lloyd_solvers`.

:class:`EuclideanTeam` is the centralized form of every robot's decentralized ``lloyd`` update
(:func:`coverage_ros.core.geodesic.euclidean.euclidean_cell`): every cell's mass, centroid and
cost from its runs of grid cells row by row (:mod:`coverage_ros.core.offline.power_rows`: two
look-ups in running sums per row instead of labelling every grid cell, which
:meth:`EuclideanTeam.reference_step` does for the parity tests), each centroid projected to a
feasible cell as the decentralized update does. :class:`GeodesicTeam` is the same with geodesic
cells.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.offline.lloyd_solvers import SOLVERS, LloydSolution, solve_lloyd
from coverage_ros.core.offline.power_rows import RowNearest, RowSums, row_runs
from coverage_ros.errors import ConfigError


@dataclass(frozen=True)
class TeamStep:
    """One tessellation of the team at ``positions``."""

    positions: np.ndarray  # (n, 2) [m] map frame
    masses: np.ndarray  # (n,) sum w dA over each cell
    costs: np.ndarray  # (n,) sum (|q - p_i|^2 - R_i^2) w dA over each cell
    centroids: np.ndarray  # (n, 2) [m] mass centroids (a robot with no mass: its position)
    goals: np.ndarray  # (n, 2) [m] centroids projected to feasible cells
    cells: np.ndarray | Callable[[], np.ndarray] = field(repr=False)  # labels, or their maker
    geodesic: bool = False  # the cells and costs are the geodesic tessellation's as well

    @cached_property
    def labels(self) -> np.ndarray:
        """``(H, W)`` int: the robot whose cell holds each grid cell (-1: blocked); made when
        first asked for (a solver's steps need the sums only)."""
        return self.cells() if callable(self.cells) else self.cells

    @property
    def cost(self) -> float:
        return float(self.costs.sum())

    @property
    def step_length(self) -> float:
        """[m] the longest Lloyd step of any robot."""
        return float(np.hypot(*(self.goals - self.positions).T).max())


class EuclideanTeam:
    """Euclidean power Voronoi team steps on a domain's grid (see module docstring)."""

    overshoots = False  # (a step to the centroids lowers H; a projected goal may not)

    def __init__(self, domain: CoverageDomain) -> None:
        if any(domain.graph.wrap):
            raise ConfigError.at("domain", "a wrapping chart has no Euclidean Voronoi cells",
                                 domain.graph.wrap)
        self.domain = domain
        H, W = domain.shape
        res = domain.resolution
        # Grid-frame metres: distances are those of the map frame (rotation + translation).
        self._cx = (np.arange(W) + 0.5) * res
        self._cy = (np.arange(H) + 0.5) * res
        w = np.where(domain.free, domain.mass_element, 0.0)
        self._rows = RowSums(w, self._cx, self._cy)
        self._w = w.ravel()
        self._free = domain.free.ravel()
        # a centroid's cell is a feasible goal where it is free with positive density
        self._feasible = domain.free & (domain.density > 0)
        rows, cols = np.nonzero(domain.free)
        box = domain.free[rows.min():rows.max() + 1, cols.min():cols.max() + 1] \
            if len(rows) else domain.free
        #: Straight lines are geodesics and the free cells fill a rectangle: every free cell
        #: sees every point of it, so the geodesic (visibility) tessellation is this one.
        self.is_geodesic = bool(domain.sees_straight and box.all())

    @cached_property
    def _nearest(self) -> tuple[RowNearest, RowNearest]:
        """Where an infeasible centroid goes: the nearest cell of the own cell with positive
        weight, else (a cell without weight) the nearest free one; made when first needed."""
        return RowNearest(self._w.reshape(self.domain.shape) > 0), RowNearest(self.domain.free)

    def _to_frame(self, positions: np.ndarray) -> np.ndarray:
        return self.domain.to_grid(positions) * self.domain.resolution

    def _to_map(self, frame_xy: np.ndarray) -> np.ndarray:
        return self.domain.to_map(np.asarray(frame_xy) / self.domain.resolution)

    def labels(self, positions: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """``(H, W)`` power Voronoi labels of every grid cell (ties: the lower index), as
        :func:`coverage_ros.core.geodesic.euclidean.euclidean_labels` but on blocked cells too."""
        g = self._to_frame(positions)
        r2 = np.asarray(weights, dtype=np.float64) ** 2
        dx = (self._cx[None, :] - g[:, :1]) ** 2  # (n, W)
        dy = (self._cy[None, :] - g[:, 1:]) ** 2 - r2[:, None]  # (n, H)
        best = dy[0][:, None] + dx[0][None, :]
        labels = np.zeros(best.shape, dtype=np.int32)
        d = np.empty_like(best)  # (buffers used again: no allocation per robot)
        closer = np.empty(best.shape, dtype=bool)
        for k in range(1, len(g)):
            np.add(dy[k][:, None], dx[k][None, :], out=d)
            np.less(d, best, out=closer)
            labels[closer] = k
            np.minimum(best, d, out=best)
        return labels

    def step(self, positions: np.ndarray, weights: np.ndarray | None = None) -> TeamStep:
        """The team's cells, masses, costs, centroids and goals at ``positions (n, 2)``: the
        sums over every cell from its runs of grid cells row by row
        (:mod:`coverage_ros.core.offline.power_rows`); the labels only when asked for."""
        P, R = self._inputs(positions, weights)
        g = self._to_frame(P)
        runs = row_runs(g[:, 0], g[:, 1], R * R, self._cx, self._cy)

        def project(i: int, cf: np.ndarray) -> np.ndarray | None:
            for rows in self._nearest:
                rc = rows.nearest(runs.start[i], runs.stop[i], cf, self._cx, self._cy)
                if rc is not None:
                    return np.array([self._cx[rc[1]], self._cy[rc[0]]])
            return None

        return self._finish(P, R, g, self._rows.moments(runs),
                            lambda: runs.labels(self.domain.shape[1]), project)

    def reference_step(self, positions: np.ndarray,
                       weights: np.ndarray | None = None) -> TeamStep:
        """:meth:`step` the obvious way, for the parity tests and benchmarks: every grid cell
        labelled (:meth:`labels`), the sums over the labels."""
        P, R = self._inputs(positions, weights)
        lab = self.labels(P, R)
        flat = lab.ravel()
        n = len(P)
        S = np.stack([np.bincount(flat, weights=v.ravel(), minlength=n)
                      for v in self._rows.cell_values()], axis=1)
        return self._finish(P, R, self._to_frame(P), S, lambda: lab,
                            lambda i, cf: self._project(i, cf, flat))

    @staticmethod
    def _inputs(positions: np.ndarray, weights: np.ndarray | None) -> tuple[np.ndarray, ...]:
        P = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        R = np.zeros(len(P)) if weights is None else np.asarray(weights, dtype=np.float64)
        return P, R

    def _finish(self, P: np.ndarray, R: np.ndarray, g: np.ndarray, S: np.ndarray,
                labels: Callable[[], np.ndarray],
                project: Callable[[int, np.ndarray], np.ndarray | None]) -> TeamStep:
        """The step at ``P`` (``g`` in the grid frame) from every cell's sums ``S (n, 4)``
        (mass, first moments, second moment in the grid frame), a maker of the ``(H, W)``
        labels of every grid cell and ``project``: robot i's goal (grid frame) for a centroid
        ``cf`` on a cell that is not feasible."""
        mass = S[:, 0]
        costs = S[:, 3] - 2.0 * (g * S[:, 1:3]).sum(axis=1) + ((g * g).sum(axis=1) - R * R) * mass
        safe = np.where(mass > 0, mass, 1.0)
        cf = np.where(mass[:, None] > 0, S[:, 1:3] / safe[:, None], g)
        centroids = self._to_map(cf)
        H, W = self.domain.shape
        res = self.domain.resolution
        r = np.floor(cf[:, 1] / res).astype(np.int64)
        c = np.floor(cf[:, 0] / res).astype(np.int64)
        ok = (r >= 0) & (r < H) & (c >= 0) & (c < W)
        ok[ok] = self._feasible[r[ok], c[ok]]
        goals = centroids.copy()
        for i in np.flatnonzero(~ok):  # as project_feasible: the nearest cell centre of the
            q = project(int(i), cf[i])  # own cell with positive weight (or free), else centroid
            if q is not None:
                goals[i] = self._to_map(q)[0]
        return TeamStep(P, mass, costs, centroids, goals,
                        lambda: np.where(self.domain.free, labels(), -1), self.is_geodesic)

    def _project(self, i: int, cf: np.ndarray, flat: np.ndarray) -> np.ndarray | None:
        """The obvious projection over robot i's labelled cells (:meth:`reference_step`)."""
        W = self.domain.shape[1]
        own = flat == i
        pool = np.flatnonzero(own & (self._w > 0))
        if len(pool) == 0:
            pool = np.flatnonzero(own & self._free)
        if len(pool) == 0:
            return None
        xy = np.stack([self._cx[pool % W], self._cy[pool // W]], axis=1)
        nearest: np.ndarray = xy[int(np.argmin(((xy - cf) ** 2).sum(axis=1)))]
        return nearest


class GeodesicTeam:
    """The same team step with geodesic power Voronoi cells and the generalized Lloyd control
    (Bhattacharya et al. 2014): every robot's :func:`geodesic_cell` over the whole domain, all
    from one tessellation (:func:`coverage_ros.core.offline.geodesic_team.team_cells`: one
    search, sums over the labels); :meth:`reference_step` runs the robots' own updates, for
    the parity tests. ``centroids`` are the virtual centroids (position + control), ``goals``
    their reachable part. On a grid whose free space fills a small part of it (wide unknown
    margins), a step whose robots all stand on free cells runs on the window that holds the
    free space (:mod:`coverage_ros.core.geodesic.crop`: the same cells and sums)."""

    overshoots = True  # (a generalized Lloyd step is a gradient step of size 1 / m_i)

    def __init__(self, domain: CoverageDomain, method: str = "auto") -> None:
        self.domain = domain
        self.method = method

    def step(self, positions: np.ndarray, weights: np.ndarray | None = None) -> TeamStep:
        P, R = EuclideanTeam._inputs(positions, weights)
        from coverage_ros.core.geodesic.crop import window_of
        from coverage_ros.core.offline.geodesic_team import team_cells  # graph searches: scipy

        cut = window_of(self.domain, P)
        if cut is None:
            cells = team_cells(self.domain, P, R, self.method)
            return TeamStep(P, cells.masses, cells.costs, P + cells.controls, cells.goals,
                            cells.cells)
        inner, window = cut
        cells = team_cells(inner, P, R, self.method)
        shape = self.domain.shape

        def labels() -> np.ndarray:
            whole = np.full(shape, -1, dtype=np.int32)
            whole[window] = cells.cells()
            return whole

        return TeamStep(P, cells.masses, cells.costs, P + cells.controls, cells.goals, labels)

    def reference_step(self, positions: np.ndarray,
                       weights: np.ndarray | None = None) -> TeamStep:
        """:meth:`step` as every robot's own decentralized update over the whole domain
        (:func:`geodesic_cell` with ``whole=True``; with equal weights they share one search)."""
        P, R = EuclideanTeam._inputs(positions, weights)
        from coverage_ros.core.geodesic.cell import geodesic_cell  # graph searches: scipy, only
        from coverage_ros.core.geodesic.tessellation import Generator  # for this team

        gens = [Generator(p, r) for p, r in zip(P, R, strict=True)]
        cells = [geodesic_cell(self.domain, g, gens[:i] + gens[i + 1:], method=self.method,
                               whole=True) for i, g in enumerate(gens)]
        labels = np.full(self.domain.shape, -1, dtype=np.int32)
        for i, c in enumerate(cells):
            labels.ravel()[c.nodes] = i
        return TeamStep(P, np.array([c.mass for c in cells]), np.array([c.cost for c in cells]),
                        P + np.array([c.control for c in cells]),
                        np.array([c.goal for c in cells]), labels)


__all__ = ["SOLVERS", "EuclideanTeam", "GeodesicTeam", "LloydSolution", "TeamStep",
           "solve_lloyd"]
