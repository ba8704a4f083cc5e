"""Lee & Lee (2024), decentralized: alpha-CVT where each robot knows only what its neighbours
publish.

The paper is centralized (:mod:`coverage_ros.core.strategies.acvt.dropout`); its future work
is this form. Protocol - every robot publishes, each control period, a :class:`SharedState` with

* ``position`` - its position [m];
* ``mass`` - the mass of its own cell (Eq. 1/15/17 cell among the neighbours it knows, the
  visible part of it with ``visibility``, Eq. 12) at that position;
* ``extra["reach"]`` - R_i = v_max * 1 s [m] (Eq. 16; the common time cancels), so that
  heterogeneous neighbours weigh cells (Eq. 17) and masses (Eq. 18) alike;
* ``extra["dropout"]`` - 1 while its dropout phase is on, 0 once it has ended;
* ``extra["greedy"]`` - 1 if it counted itself greedy in its last update (informational).

and on each update a robot

1. computes its own cell and mass from its position and its neighbours' positions (and
   reaches);
2. while its dropout is on, takes the masses it knows - its own and each neighbour's published
   one, normalised by pi R^2 for heterogeneous teams - and computes their local I (Eq. 9), feeds
   it to the low-pass-filtered Delta I switch of Alg. 2 (epsilon), and the local threshold
   tau_drop = k / (k - 1) * mean(M) over those k masses (Alg. 1); no mass at or above tau_drop
   ends the dropout, as in the paper;
3. if its own mass reaches tau_drop it is greedy: like a greedy agent of Alg. 1 it keeps its
   place during the dropout and then takes the ordinary CVT step - the goal is the (projected,
   Eq. 8) centroid of its full cell;
4. otherwise it drops the neighbours whose published mass reaches its tau_drop, jumps (virtually)
   to the projected centroid of its cell among the remaining ones (Alg. 1, lines 9-10), and,
   reinserting them, takes the projected centroid of its full cell about that point as its
   goal (Alg. 2, lines 9-10) - both half-steps of an iteration in one update, so the goal does
   not alternate between control periods;
5. once its dropout is off: plain iCVT + projection (goal = projected centroid of its cell).

With every robot hearing every other (as in
:func:`coverage_ros.core.offline.runner.run_offline`) the local threshold and I are the global
ones, computed from masses one control period old. With
partial neighbourhoods each robot balances against its neighbours only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from coverage_ros.core.metrics import mass_deviation
from coverage_ros.core.strategies.acvt.cells import CellSpec, MassCells, normalized_masses
from coverage_ros.core.strategies.acvt.dropout import DropoutSwitch, greedy_mask
from coverage_ros.core.strategies.acvt.iterations import (
    ITERATION_KEY,
    MoveIterations,
    awaiting_mass,
    peer_counts,
)
from coverage_ros.core.strategies.acvt.params import AcvtParams
from coverage_ros.core.strategies.acvt.plans import heard_plan, plan_extras
from coverage_ros.core.strategies.acvt.prediction import team_metric
from coverage_ros.core.strategies.acvt.relocation import (
    DEFAULT_LEVEL_WINDOW,
    MetricLevel,
    Relocation,
    best_relocation,
    movers,
    own_future,
    way_back,
)
from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    SharedState,
    Strategy,
    StrategyContext,
    StrategyDetails,
)

#: [s] travel time t of Eq. 16 that turns v_max into the reach R_i; any value gives the same
#: cells and metric (it cancels), 1 s makes R_i read as metres per second.
REACH_TIME = 1.0
#: A robot within this many convergence tolerances of its goal counts as settled for the
#: relocation (live robots hover 5-9 cm from goals that move with their neighbours' jitter).
SETTLED_FACTOR = 3.0
#: Plans (relocations of a team of mixed reaches, :mod:`.plans`) one robot may make, besides
#: the way back (:func:`.relocation.way_back`).
MAX_PLANS = 4


@dataclass(frozen=True)
class AcvtDetails(StrategyDetails):
    greedy: bool  # own mass reached tau_drop in this update
    dropout: bool  # the dropout phase is on
    dropped: tuple[int, ...]  # robot ids of the neighbours dropped in this update
    local_deviation: float  # mass deviation I over the masses heard (NaN outside dropout)
    tau_drop: float  # the dropout threshold (NaN outside dropout)
    centroid: np.ndarray | None  # (2,) [m] own cell's centroid (None: empty cell)
    relocation: np.ndarray | None = None  # (2,) [m] where the robot relocates to, if it does
    predicted: float = math.nan  # the team metric predicted after that relocation


class AcvtStrategy(Strategy):
    """Alpha-CVT (iCVT + projection with agent dropout and reinsertion), decentralized."""

    name: ClassVar[str] = "acvt"
    Params: ClassVar[type] = AcvtParams
    params: AcvtParams

    def __init__(self, context: StrategyContext, params: AcvtParams | None = None) -> None:
        super().__init__(context, params)
        self.cells = MassCells(context.domain)
        self.dropout = self.params.dropout_config(self.cells.regions)
        self.spec = self.params.cell_spec()
        self.speed_weighted = bool(self.params.speed_weighted)
        self.reach = context.robot.v_max * REACH_TIME
        self.switch = DropoutSwitch(self.dropout)
        self.iterations = MoveIterations(context.robot.v_max,
                                         SETTLED_FACTOR * context.convergence_tolerance)
        self.relocation = self.params.relocation_config(self.cells.regions)
        self._relocating: np.ndarray | None = None  # (2,) [m] target of a relocation under way
        self._relocations = 0
        self._level = MetricLevel(DEFAULT_LEVEL_WINDOW, self.relocation.margin)
        self._levelling = False  # waiting for the team's metric to level off to predict
        # The team's metric after the dropout, for convergence: a robot is not converged while
        # it still falls by the paper's epsilon (:meth:`_team_falling`).
        self._team_level = MetricLevel(DEFAULT_LEVEL_WINDOW, self.dropout.epsilon)
        self._checked: np.ndarray | None = None  # team positions of the last prediction
        self._plan: dict[str, float] = {}  # the extras of the plan this robot publishes
        self._plans = 0  # plans made (mixed reaches: this robot predicts for its neighbourhood)
        self._carried: set[tuple[int, int]] = set()  # (planner, seq) of the plans carried out
        # (metric, positions, robot ids) of the lowest own future (:func:`.own_future`) of a
        # settled team this robot predicted from (mixed reaches): where the way back leads
        self._best_future: tuple[float, np.ndarray, np.ndarray] | None = None

    def shared_state(self, obs: Observation) -> SharedState:
        return SharedState(position=obs.position.copy(), weight=self.context.weight,
                           extra=self._extra(False))

    def _extra(self, greedy: bool, settled: bool = False) -> dict[str, float]:
        return {"reach": self.reach, "dropout": float(self.switch.active),
                ITERATION_KEY: float(self.iterations.count),
                "greedy": float(greedy), "settled": float(settled),
                "relocating": float(self._relocating is not None), **self._plan}

    # ------------------------------------------------------------------ cells
    def _own_cell(self, P: np.ndarray, reach: np.ndarray | None,
                  own: int) -> tuple[np.ndarray, float, np.ndarray | None]:
        """Labels of the mass cells among ``P (k, 2)`` (row ``own`` = this robot), the own mass
        and the own centroid (None for an empty cell); visibility applies to the own cell."""
        spec = self.spec
        if spec.visibility:
            spec = CellSpec(False, spec.scale, spec.gap_penalty)
        labels = self.cells.labels(P, reach, spec)
        if self.spec.visibility:
            labels = self.cells.restrict_to_visible(labels, P, agents=[own])
        masses, centroids = self.cells.stats(np.where(labels == own, 0, -1), 1)
        centroid = None if masses[0] <= 0 else centroids[0]
        return labels, float(masses[0]), centroid

    def _goal(self, P: np.ndarray, reach: np.ndarray | None, own: int) -> np.ndarray:
        """Projected (Eq. 8) centroid of the own cell among ``P`` (own position if empty)."""
        _, _, centroid = self._own_cell(P, reach, own)
        goal: np.ndarray = self.cells.project(P[own] if centroid is None else centroid)[0]
        return goal

    # ------------------------------------------------------------------ update
    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        p = obs.position
        # Generators in robot-id order: ties (coincident robots) go to the lowest id in every
        # robot's computation alike, so a shared cell has a single owner.
        ids = np.array([obs.robot_id] + [n.robot_id for n in neighbours])
        order = np.argsort(ids, kind="stable")
        states = [None] + [n.state for n in neighbours]
        P = np.vstack([p[None, :]] + [np.asarray(n.position, float)[None, :2]
                                      for n in neighbours])[order]
        reach = np.array([self.reach] + [float(n.state.extra.get("reach", self.reach))
                                         for n in neighbours])[order]
        own = int(np.flatnonzero(order == 0)[0])
        if not self.speed_weighted or np.allclose(reach, reach[0]):
            reach_arg = None  # equal reaches: Eq. 17 is Eq. 1 and M^h is M / const
        else:
            reach_arg = reach
        labels, mass, centroid = self._own_cell(P, reach_arg, own)

        greedy, dropped, local_i, tau = False, np.zeros(0, dtype=np.int64), math.nan, math.nan
        published = np.full(len(P), np.nan)
        for row, src in enumerate(order):
            st = states[src]
            if st is not None and st.mass is not None and math.isfinite(st.mass):
                published[row] = float(st.mass)
        published[own] = mass
        idx = np.flatnonzero(np.isfinite(published))
        heard = [states[src] for src in order if states[src] is not None]
        sampled = False
        if self.switch.active and len(idx) > 1:
            m = published[idx]
            weighed = m if reach_arg is None else normalized_masses(m, reach[idx])
            local_i = mass_deviation(weighed)
            mask = greedy_mask(weighed, self.dropout.drop_factor)
            k = len(weighed)
            factor = k / (k - 1) if self.dropout.drop_factor is None else self.dropout.drop_factor
            tau = factor * float(weighed.mean())
            # Alg. 2's end tests, once per iteration (:mod:`.iterations`), on the masses of
            # every acvt robot heard (a robot yet to make its first update has none: a test
            # on the masses of the first few robots up could end the dropout at once).
            peers = peer_counts(heard)
            if not awaiting_mass(heard) and self.iterations.due(p, obs.time, peers):
                sampled = True
                self.switch.update(local_i)
                if not mask.any():
                    self.switch.stop()
            if self.switch.active and mask.any():
                greedy = bool(mask[idx == own][0])
                dropped = idx[mask & (idx != own)]

        if self.switch.active and not greedy and len(dropped):
            keep = np.ones(len(P), dtype=bool)
            keep[dropped] = False
            sub_own = int(keep[:own].sum())
            jump = self._goal(P[keep], None if reach_arg is None else reach_arg[keep], sub_own)
            P_jump = P.copy()
            P_jump[own] = jump
            goal = self._goal(P_jump, reach_arg, own)
        else:
            goal = self.cells.project(p if centroid is None else centroid)[0]
        if sampled:
            self.iterations.sampled(p, goal, obs.time, peers)

        tol = self.context.convergence_tolerance
        # Converged once the goal is reached with no dropout under way (a robot that hears
        # no neighbour's mass cannot drop out and converges like iCVT + projection). Settled -
        # what a relocation waits for - is looser: a live robot hovers a few centimetres from
        # a goal that shifts with every neighbour's jitter.
        off = float(np.hypot(*(goal - p)))
        phase = self.switch.active and len(idx) > 1
        converged = not phase and off < tol
        settled = not phase and off < SETTLED_FACTOR * tol
        mode = "greedy" if greedy else ("dropout" if self.switch.active else "cvt")
        if self._relocating is not None and float(np.hypot(*(self._relocating - p))) < tol:
            self._relocating = None  # arrived: back to iCVT + projection
        predicted = math.nan
        plan = heard_plan(obs.robot_id, heard)
        if self._relocating is None and plan is not None and plan[0] not in self._carried:
            self._carried.add(plan[0])  # a neighbour's plan names this robot: it goes
            self._relocating = plan[1]
            self._relocations += 1
        if self._relocating is None and settled:
            move = self._relocation_move(P, reach_arg, own, heard, ids[order])
            if move is not None:
                self._relocating, predicted = move.point_of(own), move.metric_after
                self._relocations += 1
        else:  # moving: a later prediction waits for the metric to level off anew
            self._level.reset()
            self._levelling = False
        if self._relocating is not None:
            goal, converged, settled, mode = self._relocating.copy(), False, False, "relocate"
        falling = self._team_falling(labels, len(P), reach_arg, phase)
        # Not converged while a prediction may yet move the team or the team still converges.
        converged = converged and not self._levelling and not falling
        mine = labels == own
        return Decision(
            goal=goal, velocity=None, cell=self.cells.nodes[mine],
            shared=SharedState(position=p.copy(), weight=self.context.weight, mass=mass,
                               extra=self._extra(greedy, settled)),
            converged=converged, cost=self.cells.cost(labels, P, own), mass=mass, mode=mode,
            settling=(self.switch.active and len(idx) > 1) or self._relocating is not None
            or self._levelling or falling,
            details=AcvtDetails(greedy=greedy, dropout=self.switch.active,
                                dropped=tuple(int(ids[order[j]]) for j in dropped),
                                local_deviation=local_i, tau_drop=tau,
                                centroid=None if centroid is None else centroid.copy(),
                                relocation=None if self._relocating is None
                                else self._relocating.copy(), predicted=predicted))

    def _team_falling(self, labels: np.ndarray, k: int, reach: np.ndarray | None,
                      phase: bool) -> bool:
        """Whether the mass deviation of the team this robot hears (``labels`` of its ``k``
        generators) still falls after the dropout: by the paper's epsilon (Alg. 2's test of a
        negligible Delta I) or more over this robot's last updates (:class:`MetricLevel`):
        Lloyd's last steps are short while the metric still falls a lot, so step lengths alone
        would count a team converged too early."""
        if phase or k < 2:
            self._team_level.reset()
            return False
        masses, _ = self.cells.stats(labels, k)
        weighed = masses if reach is None else normalized_masses(masses, reach)
        return not self._team_level.record(mass_deviation(weighed))

    def _prediction_metric(self, P: np.ndarray, reach: np.ndarray | None, own: int,
                           neighbours: list[SharedState], row_ids: np.ndarray,
                           mixed: bool) -> float | None:
        """The team's metric at ``P`` if this robot may predict a relocation from it now (see
        :meth:`_relocation_move`), else None."""
        cfg = self.relocation
        spent = self._plans > MAX_PLANS if mixed else self._relocations >= cfg.max_moves
        if not cfg.enabled or self.switch.active or spent or len(P) < 2:
            return None
        if not all(st.extra.get("settled", 0.0) == 1.0 and st.extra.get("dropout", 1.0) == 0.0
                   and st.extra.get("relocating", 0.0) == 0.0 for st in neighbours):
            return None
        still = 2.0 * self.context.convergence_tolerance  # [m] live positions jitter this much
        if (self._checked is not None and self._checked.shape == P.shape
                and float(np.hypot(*(self._checked - P).T).max()) < still):
            return None
        if mixed and row_ids[own] != row_ids.min():
            return None
        _, masses, metric = team_metric(self.cells, self.spec, P, reach)
        if not mixed and own not in movers(masses, reach, cfg.movers):
            return None
        return metric

    def _relocation_move(self, P: np.ndarray, reach: np.ndarray | None, own: int,
                         neighbours: list[SharedState], row_ids: np.ndarray
                         ) -> Relocation | None:
        """The relocation this robot makes now, if any (:mod:`.relocation`): only with its
        dropout over, every neighbour settled, out of the dropout and not relocating, and its
        own (normalised) mass among the ``movers`` least of the team at ``P (k, 2)`` (row
        ``own``); those robots all predict the same relocation, and only the robot it names
        moves - so that in a team that hears everyone one robot at a time relocates. In a team
        of mixed reaches, where an exchange or a swap names several robots, the robot of lowest
        id among those heard (``row_ids``: the robot id of every row of ``P``) predicts alone
        and publishes the plan (:mod:`.plans`). A team configuration that was predicted already
        is not predicted again, and none is predicted before the team's metric has levelled off
        over this robot's last updates (:class:`~.relocation.MetricLevel`)."""
        cfg = self.relocation
        mixed = reach is not None and len(np.unique(reach)) > 1 and cfg.exchanges > 0
        metric = self._prediction_metric(P, reach, own, neighbours, row_ids, mixed)
        self._level.margin = cfg.margin_for(reach)
        # Predict from a team that has stopped converging on its own (MetricLevel); any update
        # in which this robot may not predict starts the wait over.
        self._levelling = metric is not None and not self._level.record(metric)
        if metric is None:
            self._level.reset()
        if metric is None or self._levelling:
            return None
        self._checked = P.copy()
        future = own_future(self.cells, self.spec, P, reach, cfg) if mixed else None
        if future is not None and (self._best_future is None
                                   or future[1] < self._best_future[0]):
            self._best_future = (future[1], future[0], row_ids.copy())
        if future is not None and self._plans >= MAX_PLANS:
            move = way_back(self._best_future, metric, P, row_ids, self._level.margin,
                            self.context.convergence_tolerance)
        else:
            move = best_relocation(self.cells, self.spec, P, reach, cfg, future)
        self._level.reset()
        if move is not None and mixed:
            self._plans += 1
            self._plan = plan_extras(int(row_ids[own]), self._plans,
                                     {int(row_ids[a]): pt for a, pt in zip(
                                         move.agents, move.points, strict=True)})
            self._carried.add((int(row_ids[own]), self._plans))
        return move if move is not None and own in move.agents else None
