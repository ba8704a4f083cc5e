"""Geodesic power Voronoi cells and the generalized Lloyd control (Bhattacharya et al. 2014);
the machinery is in :mod:`coverage_ros.core.geodesic`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from coverage_ros.core.geodesic.cell import SearchCache, geodesic_cell
from coverage_ros.core.geodesic.tessellation import METHODS, Generator, cell_cost_about
from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    SharedState,
    Strategy,
    StrategyDetails,
)
from coverage_ros.errors import ConfigError

#: A monotone-step cost search reaches this many longest edges beyond the cell and the step
#: to the goal ...
COST_SLACK_EDGES = 4.0
#: ... and this factor beyond the step's own length (the metric may lengthen it).
COST_STEP_FACTOR = 1.1


@dataclass(frozen=True)
class GeodesicParams:
    """Settings of the ``geodesic`` strategy."""

    #: sources and tangents: auto, visibility, paper or lookahead (see ``resolve_method``)
    method: str = "auto"

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ConfigError.at("method", "unknown method", self.method, f"one of {METHODS}")


@dataclass(frozen=True)
class GeodesicDetails(StrategyDetails):
    method: str  # the method asked for
    passes: int  # searches run (1 when the first search radius sufficed; 0: a sibling's reused)
    searched: int  # nodes in the pruned search graph
    neighbours: tuple[int, ...]  # robot ids of the neighbours whose cells border the own
    cell_radius: float  # max geodesic distance over the own cell
    next_vertex: np.ndarray  # (2,) [m] graph neighbour best aligned with the control (paper)


class GeodesicStrategy(Strategy):
    """Go to the own geodesic cell's virtual centroid (gradient step of Eq. 8)."""

    name: ClassVar[str] = "geodesic"
    Params: ClassVar[type] = GeodesicParams
    params: GeodesicParams

    def __init__(self, context, params: GeodesicParams | None = None) -> None:
        super().__init__(context, params)
        self.cache = SearchCache()

    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        own = Generator(obs.position, self.context.weight)
        others = [Generator(n.position, n.state.weight) for n in neighbours]
        cell = geodesic_cell(self.context.domain, own, others, cache=self.cache,
                             method=self.params.method, reuse=self.context.search_reuse)
        step = float(np.hypot(*(cell.goal - obs.position)))
        return Decision(
            goal=cell.goal, velocity=None, cell=cell.nodes,
            shared=SharedState(position=obs.position.copy(), weight=self.context.weight,
                               mass=cell.mass),
            converged=step < self.context.convergence_tolerance, cost=cell.cost,
            mass=cell.mass, mode="lloyd",
            details=GeodesicDetails(
                method=self.params.method, passes=cell.passes, searched=cell.searched_nodes,
                neighbours=tuple(neighbours[k].robot_id for k in cell.neighbours),
                cell_radius=cell.cell_radius, next_vertex=cell.next_vertex))

    def cost_about(self, decision: Decision, point: np.ndarray) -> float | None:
        details = decision.details
        if not isinstance(details, GeodesicDetails) or len(decision.cell) == 0:
            return None
        domain = self.context.domain
        # One search limit for every point between the robot and its goal.
        goal = decision.goal if decision.goal is not None else decision.shared.position
        step = float(np.hypot(*(goal - decision.shared.position)))
        reach = (details.cell_radius + COST_STEP_FACTOR * step
                 / max(domain.metric_lower_bound, 1e-9)
                 + COST_SLACK_EDGES * domain.graph.max_edge_cost)
        return cell_cost_about(domain, decision.cell, np.asarray(point, dtype=np.float64),
                               self.context.weight, reach, self.params.method)
