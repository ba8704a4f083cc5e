"""Seed 000: geodesic power Voronoi cells and the generalized Lloyd control."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any, ClassVar

from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    SharedState,
    Strategy,
    StrategyContext,
)
from coverage_ros.core.tessellation import METHODS, Generator, SearchCache, geodesic_cell
from coverage_ros.errors import ConfigError


class GeodesicStrategy(Strategy):
    """Go to the own geodesic cell's virtual centroid (gradient step of Eq. 8)."""

    name: ClassVar[str] = "geodesic"

    def __init__(self, context: StrategyContext, method: str = "auto", **params: Any) -> None:
        super().__init__(context, **params)
        if method not in METHODS:
            raise ConfigError.at("geodesic_method", "unknown method", method,
                                 f"one of {METHODS}")
        self.method = method
        self.cache = SearchCache()

    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        own = Generator(obs.position, self.context.weight)
        others = [Generator(n.position, n.state.weight) for n in neighbours]
        t0 = time.perf_counter()
        cell = geodesic_cell(self.context.domain, own, others, cache=self.cache,
                             method=self.method)
        elapsed = time.perf_counter() - t0
        step = float(((cell.goal - obs.position) ** 2).sum() ** 0.5)
        return Decision(
            goal=cell.goal, velocity=None, cell=cell.nodes,
            shared=SharedState(position=obs.position.copy(), weight=self.context.weight,
                               mass=cell.mass),
            converged=step < self.context.convergence_tolerance, cost=cell.cost,
            mass=cell.mass,
            info={"update_s": elapsed, "method": self.method, "passes": cell.passes,
                  "searched": cell.searched_nodes,
                  "neighbours": [neighbours[k].robot_id for k in cell.neighbours],
                  "cell_radius": cell.cell_radius, "next_vertex": cell.next_vertex})
