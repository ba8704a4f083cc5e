"""Classic Lloyd (Cortes et al. 2004): go to the centroid of the own Euclidean (power) Voronoi
cell; the cells are in :mod:`coverage_ros.core.geodesic.euclidean`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from coverage_ros.core.geodesic.euclidean import cell_cost_about, euclidean_cell
from coverage_ros.core.geodesic.tessellation import Generator
from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    SharedState,
    Strategy,
    StrategyDetails,
)


@dataclass(frozen=True)
class LloydDetails(StrategyDetails):
    centroid: np.ndarray  # (2,) [m] mass centroid of the own cell (before projection)


class LloydStrategy(Strategy):
    """Euclidean Voronoi cell on the free grid cells; centroid projected if infeasible."""

    name: ClassVar[str] = "lloyd"

    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        own = Generator(obs.position, self.context.weight)
        others = [Generator(n.position, n.state.weight) for n in neighbours]
        cell = euclidean_cell(self.context.domain, own, others)
        step = float(np.hypot(*(cell.goal - obs.position)))
        return Decision(
            goal=cell.goal, velocity=None, cell=cell.nodes,
            shared=SharedState(position=obs.position.copy(), weight=self.context.weight,
                               mass=cell.mass),
            converged=step < self.context.convergence_tolerance, cost=cell.cost,
            mass=cell.mass, mode="lloyd", cell_polygon=cell.polygon,
            details=LloydDetails(centroid=cell.centroid))

    def cost_about(self, decision: Decision, point: np.ndarray) -> float | None:
        if len(decision.cell) == 0:
            return None
        return cell_cost_about(self.context.domain, decision.cell,
                               np.asarray(point, dtype=np.float64), self.context.weight)
