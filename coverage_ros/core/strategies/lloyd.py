"""Classic Lloyd: go to the centroid of the own Euclidean (power) Voronoi cell."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from coverage_ros.core.euclidean import euclidean_cell
from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    SharedState,
    Strategy,
)
from coverage_ros.core.tessellation import Generator


class LloydStrategy(Strategy):
    """Euclidean Voronoi cell on the free grid cells; centroid projected if infeasible."""

    name: ClassVar[str] = "lloyd"

    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        own = Generator(obs.position, self.context.weight)
        others = [Generator(n.position, n.state.weight) for n in neighbours]
        t0 = time.perf_counter()
        cell = euclidean_cell(self.context.domain, own, others)
        elapsed = time.perf_counter() - t0
        step = float(np.hypot(*(cell.goal - obs.position)))
        return Decision(
            goal=cell.goal, velocity=None, cell=cell.nodes,
            shared=SharedState(position=obs.position.copy(), weight=self.context.weight,
                               mass=cell.mass),
            converged=step < self.context.convergence_tolerance, cost=cell.cost,
            mass=cell.mass, cell_polygon=cell.polygon,
            info={"update_s": elapsed, "centroid": cell.centroid})
