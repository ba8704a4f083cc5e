"""Relocation: the lightest agent reinserted into the heaviest cell, kept only where the team's
metric is predicted to fall (this project's addition to Lee & Lee's alpha-CVT).

Why: alpha-CVT's dropout and reinsertion (Alg. 1-2) decides how many agents each disjoint
target gets while its dropout phase runs, and that phase ends on a filtered Delta I (Eq. 10),
whatever the split is then. From some starts it ends with the wrong split - e.g. one normal
agent left among the greedy ones of an under-served target owns all of it once they are dropped,
so nobody moves - or with a CVT inside one target whose cells are unequal; then iCVT +
projection keeps that local minimum for good. Over six seeded corner clusters on two target
shapes of our own, the published rule ended at I = 0.03-0.40 (the paper's Fig. 3: 0.046).

What: once the dropout is off and the team has settled (every agent at its goal), each of the
few agents of least (normalised) mass j tries moving to the point of each of the heaviest cells
h farthest from that cell's agent (the part of the cell its owner covers worst), and the team's
iCVT + projection is run forward to convergence from there (:func:`settle`). The best of these
predictions is taken if it lowers the scenario's metric (I, I^L or I^H) by at least ``margin``;
otherwise nothing moves. Each relocation lowers the predicted metric by ``margin`` or more, so
there are finitely many. It is the dropout idea one step further: instead of the greedy agents
stepping aside, an idle one is reinserted where it is missing.

Both forms use it: the centralized :class:`~coverage_ros.core.strategies.acvt.dropout.AlphaCvt`
relocates between its iterations; in the decentralized strategy the few lightest robots of a
settled neighbourhood predict with their neighbours' published positions (and reaches) - all
finding the same relocation - and the one it names drives to its point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.strategies.acvt.cells import (
    CellSpec,
    MassCells,
    deviation_metric,
    normalized_masses,
)
from coverage_ros.errors import ConfigError

#: Fewest the predicted metric must fall by for a relocation to be made (absolute; I is a
#: share of the mean mass, so this is half a percent of it).
DEFAULT_MARGIN = 0.005
#: Heaviest cells tried for each agent that may move.
DEFAULT_CANDIDATES = 3
#: Lightest agents that may move (with mixed speeds the best agent to move is not always the
#: lightest: a slow one may be missing where a fast one is lightest).
DEFAULT_MOVERS = 3
#: iCVT + projection steps of a prediction (the arena scenarios converge in 15-40).
DEFAULT_HORIZON = 60


@dataclass(frozen=True)
class RelocationConfig:
    enabled: bool = True
    candidates: int = DEFAULT_CANDIDATES  # heaviest cells tried for each agent that may move
    movers: int = DEFAULT_MOVERS  # lightest agents that may move
    margin: float = DEFAULT_MARGIN  # the predicted metric must fall by at least this
    horizon: int = DEFAULT_HORIZON  # iCVT + projection steps of a prediction
    tolerance: float = 0.01  # [m] a prediction has converged when no agent moves farther
    energy_slack: float = 0.0  # share by which Eq. 2's H may rise with a relocation
    max_moves: int = 20  # relocations of one run (centralized) or one robot (decentralized)

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool | np.bool_):
            raise ConfigError.at("relocate", "must be true or false", self.enabled)
        for name in ("candidates", "movers", "horizon", "max_moves"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError.at(f"relocation.{name}", "must be an integer >= 1", value)
        for name in ("margin", "tolerance"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError.at(f"relocation.{name}", "must be a finite number > 0", value)
        slack = self.energy_slack
        if not (isinstance(slack, int | float) and math.isfinite(slack) and slack >= 0):
            raise ConfigError.at("relocation.energy_slack", "must be a finite number >= 0",
                                 slack)


@dataclass(frozen=True)
class Relocation:
    """A relocation worth making: agent ``agent`` goes to ``point``."""

    agent: int  # index of the relocated agent (one of the lightest)
    into: int  # index of the agent whose cell it enters (a heaviest one)
    point: np.ndarray  # (2,) [m] where it goes
    metric_before: float
    metric_after: float  # predicted, after the team re-converges


def cvt_step(cells: MassCells, spec: CellSpec, positions: np.ndarray,
             reach: np.ndarray | None, movers: np.ndarray | None = None,
             projection: bool = True) -> np.ndarray:
    """One iCVT (+ projection, Eq. 8) step of the agents ``movers`` (bool mask; all by
    default) on the partition among themselves; the others keep their place. An agent with an
    empty cell keeps its position as virtual target (then projected). ``(k, 2)`` [m] in and
    out."""
    P = np.asarray(positions, dtype=np.float64)
    idx = np.arange(len(P)) if movers is None else np.flatnonzero(movers)
    sub_reach = None if reach is None else reach[idx]
    labels = cells.labels(P[idx], sub_reach, spec)
    _, centroids = cells.stats(labels, len(idx))
    virt = np.where(np.isnan(centroids), P[idx], centroids)
    out = P.copy()
    out[idx] = cells.project(virt) if projection else virt
    return out


def team_metric(cells: MassCells, spec: CellSpec, positions: np.ndarray,
                reach: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, float]:
    """``(labels (N,), masses (k,), metric)`` of the partition at ``positions``: I (Eq. 9),
    I^L (Eq. 13) or I^H (Eq. 18), as the paper uses for the scenario."""
    labels = cells.labels(positions, reach, spec)
    masses, _ = cells.stats(labels, len(positions))
    return labels, masses, deviation_metric(masses, cells.total, reach, spec.visibility)


def coverage_energy(cells: MassCells, labels: np.ndarray, positions: np.ndarray) -> float:
    """Eq. 2: H = sum of |s - p_i|^2 rho(s) ds over each agent's labelled cells (uncovered
    cells count nothing)."""
    ok = labels >= 0
    d = cells.xy[ok] - np.asarray(positions, dtype=np.float64)[labels[ok]]
    return float(((d * d).sum(axis=1) * cells.wdA[ok]).sum())


def settle(cells: MassCells, spec: CellSpec, positions: np.ndarray, reach: np.ndarray | None,
           horizon: int, tolerance: float) -> np.ndarray:
    """iCVT + projection from ``positions`` until no agent moves farther than ``tolerance`` [m]
    or ``horizon`` steps have run; the positions reached."""
    P = np.asarray(positions, dtype=np.float64)
    for _ in range(horizon):
        new = cvt_step(cells, spec, P, reach)
        moved = float(np.hypot(*(new - P).T).max()) if len(P) else 0.0
        P = new
        if moved < tolerance:
            break
    return P


def insertion_point(cells: MassCells, labels: np.ndarray, positions: np.ndarray,
                    owner: int) -> np.ndarray | None:
    """``(2,)`` [m]: the mass cell of ``owner``'s cell farthest from ``owner`` (None for an
    empty cell)."""
    own = np.flatnonzero(labels == owner)
    if len(own) == 0:
        return None
    d2 = ((cells.xy[own] - positions[owner]) ** 2).sum(axis=1)
    return cells.xy[own[int(np.argmax(d2))]].copy()


def movers(masses: np.ndarray, reach: np.ndarray | None, count: int) -> list[int]:
    """The ``count`` agents of least (reach-normalised) mass, lightest first (ties: the lowest
    index) - the agents :func:`best_relocation` may move."""
    weighed = masses if reach is None else normalized_masses(masses, reach)
    return [int(j) for j in np.argsort(weighed, kind="stable")[:count]]


def best_relocation(cells: MassCells, spec: CellSpec, positions: np.ndarray,
                    reach: np.ndarray | None, config: RelocationConfig) -> Relocation | None:
    """Of the relocations of each of the ``movers`` lightest agents into each of the
    ``candidates`` heaviest cells, the one that lowers the predicted metric most, if by at
    least ``margin``; else None. ``positions (k, 2)`` [m] should be a settled configuration.
    Deterministic: robots that know the same positions find the same relocation."""
    P = np.asarray(positions, dtype=np.float64)
    if len(P) < 2:
        return None
    labels, masses, before = team_metric(cells, spec, P, reach)
    energy = coverage_energy(cells, labels, P)
    weighed = masses if reach is None else normalized_masses(masses, reach)
    heavy = [int(h) for h in np.argsort(-weighed, kind="stable")]
    best: Relocation | None = None
    for j in movers(masses, reach, config.movers):
        for h in [h for h in heavy if h != j][:config.candidates]:
            point = insertion_point(cells, labels, P, h)
            if point is None:
                continue
            Q = P.copy()
            Q[j] = point
            Q = settle(cells, spec, Q, reach, config.horizon, config.tolerance)
            labels_q, _, after = team_metric(cells, spec, Q, reach)
            if after > before - config.margin or (best is not None
                                                  and after >= best.metric_after):
                continue
            # Never at the cost of coverage: a move that only trades the masses' balance for
            # a worse covered area (Eq. 2) is not made (on one connected area with a uniform
            # density a lower I can mean a higher H).
            if coverage_energy(cells, labels_q, Q) > energy * (1.0 + config.energy_slack):
                continue
            best = Relocation(j, h, point, before, after)
    return best
