"""Geodesic power Voronoi cells and the generalized Lloyd control (Bhattacharya et al. 2014);
the machinery is in :mod:`coverage_ros.core.geodesic`. With ``escape`` (the default), a settled
robot whose cell is worth less than a split of a neighbour's moves there by handover
(:mod:`coverage_ros.core.strategies.handover`): Lloyd's local optima with a robot shut in a
dead-end room are left when a bound on the cost of the cells around the move, or the team's own
descent from it, says H drops."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from coverage_ros.core.geodesic.cell import SearchCache, geodesic_cell
from coverage_ros.core.geodesic.tessellation import METHODS, Generator
from coverage_ros.core.geodesic.whole_map import cell_cost_about
from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    SharedState,
    Strategy,
    StrategyContext,
    StrategyDetails,
)
from coverage_ros.core.strategies.handover import Handover, HandoverSettings
from coverage_ros.core.strategies.handover.published import held
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
    #: leave a cell for a neighbour's by handover when the pair's bound says H drops
    escape: bool = True
    #: least saving of the bound, as a share of the pair's cost (hysteresis against moves
    #: that gain little)
    escape_gain: float = 0.01
    #: ... and as a share of the H of all the robot hears: a robot crosses a building only
    #: for a move that matters to the team (on a large map a relocation takes minutes)
    escape_team_gain: float = 0.005
    #: [m] a robot whose Lloyd step is shorter counts as settled (offers, claims) ...
    escape_settle: float = 0.1
    #: ... and shorter than this share of its cell's radius sqrt(area / pi) as well: on
    #: small cells a step of a few cm is still a large part of the descent left
    escape_settle_share: float = 0.035
    #: [updates] after a relocation or a dropped claim, before the robot claims again
    escape_cooldown: int = 10
    #: [updates] a claim waits this long for the neighbour's grant
    escape_wait: int = 5
    #: [updates] a relocating robot gives up its point after this many
    escape_transit: int = 600
    #: Lloyd steps of the second generator when a robot prices a split of its cell
    escape_steps: int = 3
    #: Lloyd steps of the re-spreading neighbours in the joint bound (enough for a neighbour
    #: to shift by a room: fewer see only the moves that pay at once)
    escape_joint_steps: int = 10
    #: rings of cells around the pair that re-spread in the joint bound, tried one after the
    #: other up to this many (1: the cells touching either; 2: also those touching these - a
    #: robot in a corner whose one neighbour cannot take its cell alone; a wider ring's move
    #: counts only if the team's own descent from it ends lower)
    escape_joint_rings: int = 2
    #: when no bound passes at Lloyd's end: this many offers (the largest first) priced by
    #: where the team's own generalized Lloyd descent goes from the move, every robot the
    #: robot hears descending, one robot per update, the least cell first (0: none)
    escape_descent_offers: int = 3
    #: starts over the cells of the robots that made those offers, for a point in each room of
    #: such a cell, priced the same way when none of the offers pays (0 or 1: off)
    escape_descent_rooms: int = 6
    #: [m] longest step of a robot along the descents that price a move (0: whole generalized
    #: Lloyd steps, as the offline team takes them; > 0: a joint bound's move too is priced by
    #: such a descent). A live robot moves at most v_max / control_rate between coverage
    #: updates (0.11 m for the default robot at 2 Hz) and so follows the gradient closely: it
    #: may stay in a room that a whole step leaves
    escape_descent_step: float = 0.0
    #: [updates] a robot claims only once it and every robot it hears have stood within its
    #: settle step (escape_settle, escape_settle_share) for this many updates; each robot's
    #: own settled test passes a robot creeping a few cm per update, as a team re-spreading
    #: after a move does for tens of seconds (0: no such wait)
    escape_still: int = 0

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ConfigError.at("method", "unknown method", self.method, f"one of {METHODS}")
        if not isinstance(self.escape, bool):
            raise ConfigError.at("escape", "must be true or false", self.escape)
        for name in ("escape_gain", "escape_team_gain", "escape_settle",
                     "escape_settle_share", "escape_descent_step"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not (
                    math.isfinite(v) and v >= 0):
                raise ConfigError.at(name, "must be a finite number >= 0", v)
        for name in ("escape_cooldown", "escape_wait", "escape_transit", "escape_steps",
                     "escape_joint_steps", "escape_joint_rings"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ConfigError.at(name, "must be an integer >= 1", v)
        for name in ("escape_descent_offers", "escape_descent_rooms", "escape_still"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ConfigError.at(name, "must be an integer >= 0", v)

    def handover(self) -> HandoverSettings:
        return HandoverSettings(gain=float(self.escape_gain),
                                team_gain=float(self.escape_team_gain),
                                settle=float(self.escape_settle),
                                settle_share=float(self.escape_settle_share),
                                cooldown=self.escape_cooldown, wait=self.escape_wait,
                                transit=self.escape_transit, steps=self.escape_steps,
                                joint_steps=self.escape_joint_steps,
                                joint_rings=self.escape_joint_rings,
                                descent_offers=self.escape_descent_offers,
                                descent_rooms=self.escape_descent_rooms,
                                descent_step=float(self.escape_descent_step),
                                still=self.escape_still)


@dataclass(frozen=True)
class GeodesicDetails(StrategyDetails):
    method: str  # the method asked for
    passes: int  # searches run (1 when the first search radius sufficed; 0: a sibling's reused)
    searched: int  # nodes in the pruned search graph
    neighbours: tuple[int, ...]  # robot ids of the neighbours whose cells border the own
    cell_radius: float  # max geodesic distance over the own cell
    next_vertex: np.ndarray  # (2,) [m] graph neighbour best aligned with the control (paper)
    relocations: int = 0  # handovers this robot made so far (escape)
    claim: int = -1  # robot id of the cell it claims or moves into (-1: none)


class GeodesicStrategy(Strategy):
    """Go to the own geodesic cell's virtual centroid (gradient step of Eq. 8)."""

    name: ClassVar[str] = "geodesic"
    Params: ClassVar[type] = GeodesicParams
    params: GeodesicParams

    def __init__(self, context: StrategyContext, params: GeodesicParams | None = None) -> None:
        super().__init__(context, params)
        self.cache = SearchCache()
        self._origins: dict[int, np.ndarray] = {}  # [m] relocating neighbours' by robot id
        self.handover = Handover(context.robot_id, context.domain, self.params.handover(),
                                 self.params.method) if self.params.escape else None

    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        own = Generator(obs.position, self.context.weight)
        # a relocating neighbour's generator counts where it left from (handover.published)
        counted = [held(n, self._origins, self.context.domain.resolution) for n in neighbours]
        others = [Generator(p, n.state.weight) for (p, _), n in zip(counted, neighbours,
                                                                      strict=True)]
        cell = geodesic_cell(self.context.domain, own, others, cache=self.cache,
                             method=self.params.method, reuse=self.context.search_reuse)
        bordering = tuple(neighbours[k].robot_id for k in cell.neighbours)
        goal, extra, busy = cell.goal, {}, False
        if self.handover is not None:
            move = self.handover.step(obs.position, self.context.weight, cell, neighbours,
                                      bordering, self.context.convergence_tolerance,
                                      arrived=any(a for _, a in counted))
            goal = cell.goal if move.goal is None else move.goal
            extra, busy = move.extra, move.busy
        relocating = goal is not cell.goal
        step = float(np.hypot(*(goal - obs.position)))
        return Decision(
            goal=goal, velocity=None, cell=cell.nodes,
            shared=SharedState(position=obs.position.copy(), weight=self.context.weight,
                               mass=cell.mass, extra=extra),
            converged=step < self.context.convergence_tolerance and not busy, cost=cell.cost,
            mass=cell.mass, mode="relocate" if relocating else "lloyd", settling=busy,
            details=GeodesicDetails(
                method=self.params.method, passes=cell.passes, searched=cell.searched_nodes,
                neighbours=bordering, cell_radius=cell.cell_radius,
                next_vertex=cell.next_vertex,
                relocations=self.handover.relocations if self.handover else 0,
                claim=self.handover.claim if self.handover else -1))

    def cost_about(self, decision: Decision, point: np.ndarray) -> float | None:
        details = decision.details
        if not isinstance(details, GeodesicDetails) or len(decision.cell) == 0 \
                or decision.mode == "relocate":
            return None  # a handover leaves the own cell: its cost says nothing of the move
        domain = self.context.domain
        # One search limit for every point between the robot and its goal.
        goal = decision.goal if decision.goal is not None else decision.shared.position
        step = float(np.hypot(*(goal - decision.shared.position)))
        reach = (details.cell_radius + COST_STEP_FACTOR * step
                 / max(domain.metric_lower_bound, 1e-9)
                 + COST_SLACK_EDGES * domain.graph.max_edge_cost)
        return cell_cost_about(domain, decision.cell, np.asarray(point, dtype=np.float64),
                               self.context.weight, reach, self.params.method)
