"""Lee & Lee (IEEE Access 2024): adaptive CVT with agent dropout and reinsertion,
in the paper's centralized form.

* iCVT + projection (Eq. 7-8): every agent jumps to the centroid of its cell, projected to
  the nearest cell with rho > 0 when it lies where rho = 0 (an agent with an empty cell
  projects its own position, which pulls stray agents into the targets).
* AgentDropout (Alg. 1): the agents whose cell mass reaches
  tau_drop = k / (k - 1) * mean(M) are *greedy*; the others do one CVT step on the
  partition without them (so they can spread into the greedy agents' areas), then all agents
  are reinserted.
* Alg. 2: dropout + reinsertion + a CVT step of all agents each iteration, until the
  low-pass-filtered improvement Delta I = I_{t-1} - I_t (Eq. 10) drops below epsilon, or no
  agent is greedy; after that plain iCVT + projection to convergence.

The cell definition (visibility, shape constraint, reach of heterogeneous agents) and the
metric (I, I^L or I^H) come from :mod:`coverage_ros.core.strategies.acvt.cells`; with visibility or
heterogeneous agents the masses in tau_drop and Delta I are the visible (Eq. 12) or
reach-normalised (Eq. 18) ones, as in the paper.

The decentralized form (the paper's future work) is the ``acvt`` strategy,
:mod:`coverage_ros.core.strategies.acvt.strategy`, which shares :func:`greedy_mask` and
:class:`DropoutSwitch` with this module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies.acvt.cells import CellSpec, MassCells, normalized_masses
from coverage_ros.core.strategies.acvt.prediction import cvt_step, team_metric
from coverage_ros.core.strategies.acvt.relocation import RelocationConfig, best_relocation
from coverage_ros.errors import ConfigError

#: Paper, Sec. II-D: the dropout ends once the filtered Delta I falls below this.
PAPER_EPSILON = 0.002
#: Weight of the newest Delta I sample in the first-order low-pass filter. The paper applies
#: "a low pass filter" without giving it; this one forgets a sample after a few iterations.
DEFAULT_FILTER_GAIN = 0.2
#: Iterations without a new lowest I (by epsilon) after which the dropout ends on separate
#: targets (the acvt strategy's ``stall_iterations: auto``; the paper's Alg. 2 has no such
#: test, so ``DropoutConfig`` leaves it off). A team in the dropout's limit cycle (greedy agents
#: taking turns, I swinging between two values) improves on nothing, but the filter started at
#: the first Delta I - the spread out of the start cluster, ~1 against epsilon's 0.002 - keeps
#: the filtered value above epsilon for ~28 iterations at gain 0.2 whatever the team does. On
#: one connected area the test would end live dropouts too early: robots in transit through a
#: corridor set no new low for many iterations.
STALL_ITERATIONS = 5


@dataclass(frozen=True)
class DropoutConfig:
    """Agent dropout and its termination (shared by the centralized and decentralized forms)."""

    enabled: bool = True  # False: iCVT + projection, the paper's baseline
    epsilon: float = PAPER_EPSILON  # threshold on the filtered Delta I (Eq. 10)
    filter_gain: float = DEFAULT_FILTER_GAIN  # in (0, 1]; 1 = no filtering
    drop_factor: float | None = None  # tau_drop = drop_factor * mean M; None = k / (k - 1)
    #: the dropout also ends after this many iterations without a new lowest I (0: never,
    #: as published; the acvt strategy uses STALL_ITERATIONS on separate targets)
    stall_iterations: int = 0

    def __post_init__(self) -> None:
        stall = self.stall_iterations
        if isinstance(stall, bool) or not (isinstance(stall, int | np.integer) and stall >= 0):
            raise ConfigError.at("stall_iterations", "must be an integer >= 0 (0: no stall test)",
                                 stall)
        if not (math.isfinite(self.epsilon) and self.epsilon > 0):
            raise ConfigError.at("epsilon", "must be a finite number > 0 (the paper: 0.002)",
                                 self.epsilon)
        if not (0.0 < self.filter_gain <= 1.0):
            raise ConfigError.at("filter_gain", "must be in (0, 1]", self.filter_gain)
        if self.drop_factor is not None and not (math.isfinite(self.drop_factor)
                                                 and self.drop_factor > 1.0):
            raise ConfigError.at("drop_factor", "must be a finite number > 1 (at 1 every agent "
                                 "of a balanced team is greedy), or None for k / (k - 1)",
                                 self.drop_factor)


def greedy_mask(masses: np.ndarray, drop_factor: float | None = None) -> np.ndarray:
    """Alg. 1, line 3: ``(k,) bool``, the agents with M_i >= tau_drop.

    tau_drop = k / (k - 1) * mean(M) (or ``drop_factor * mean(M)``). With the paper's factor
    at least one agent is never greedy, since the greedy masses sum to at most k * mean(M).

    >>> greedy_mask(np.array([1.0, 1.0, 4.0])).tolist()
    [False, False, True]
    """
    m = np.asarray(masses, dtype=np.float64)
    k = len(m)
    mean = float(m.mean()) if k else 0.0
    if k < 2 or mean <= 0.0:
        return np.zeros(k, dtype=bool)
    factor = k / (k - 1) if drop_factor is None else drop_factor
    return m >= factor * mean


class DropoutSwitch:
    """Alg. 2, lines 11-14: turns the dropout off for good once the low-pass-filtered
    Delta I = I_{t-1} - I_t falls below epsilon, or once ``stall_iterations`` samples in a row
    have not brought I below its lowest value before them by epsilon (a limit cycle).

    The filter is first order, ``f <- f + gain * (Delta I - f)``, started at the first sample.
    """

    def __init__(self, config: DropoutConfig) -> None:
        self.config = config
        self.active = config.enabled
        self.previous: float | None = None
        self.filtered: float | None = None
        self.best = math.inf  # lowest I fed
        self.stalled = 0  # samples since I last went below best - epsilon

    def update(self, metric: float) -> bool:
        """Feed I_t; returns whether the dropout is still active."""
        if not self.active or not math.isfinite(metric):
            return self.active
        if self.previous is not None:
            delta = self.previous - metric
            if self.filtered is None:
                self.filtered = delta
            else:
                self.filtered += self.config.filter_gain * (delta - self.filtered)
            if self.filtered < self.config.epsilon:
                self.active = False
        if metric < self.best - self.config.epsilon:
            self.stalled = 0
        else:
            self.stalled += 1
            if 0 < self.config.stall_iterations <= self.stalled:
                self.active = False
        self.best = min(self.best, metric)
        self.previous = metric
        return self.active

    def stop(self) -> None:
        """End the dropout (Sec. II-C: no agent reached tau_drop)."""
        self.active = False


@dataclass(frozen=True)
class AcvtConfig:
    dropout: DropoutConfig = field(default_factory=DropoutConfig)
    cells: CellSpec = field(default_factory=CellSpec)
    #: This project's relocation once the team has settled (:mod:`.relocation`); disabled,
    #: and with ``DropoutConfig(stall_iterations=0)``, the run is the paper's Alg. 2 as
    #: published. Only with the dropout and the projection
    #: on (iCVT and iCVT + projection, the paper's baselines, never relocate).
    relocation: RelocationConfig = field(default_factory=RelocationConfig)
    max_iterations: int = 300
    tolerance: float = 0.01  # [m] done when, with the dropout off, no agent moves farther
    #: Eq. 8 after every CVT step; False is plain iCVT (the paper's Fig. 3b), where a centroid
    #: may lie where rho = 0 and an agent with an empty cell stays where it is.
    projection: bool = True

    def __post_init__(self) -> None:
        if not (isinstance(self.max_iterations, int) and self.max_iterations >= 1):
            raise ConfigError.at("max_iterations", "must be an integer >= 1",
                                 self.max_iterations)
        if not (math.isfinite(self.tolerance) and self.tolerance > 0):
            raise ConfigError.at("tolerance", "must be a finite number > 0 [m]", self.tolerance)


@dataclass(frozen=True)
class AcvtResult:
    positions: np.ndarray  # (T + 1, k, 2) [m] after the initial CVT step and each iteration
    metric: np.ndarray  # (T + 1,) I / I^L / I^H of the partition at those positions
    greedy: np.ndarray  # (T,) number of greedy (dropped out) agents per iteration
    dropout_iterations: int  # iterations run with the dropout active
    iterations: int
    converged: bool
    labels: np.ndarray  # (N,) final owner of every mass cell (MassCells order), -1 uncovered
    masses: np.ndarray  # (k,) final cell masses (visible ones with visibility)
    relocations: int = 0  # agents relocated once settled (:mod:`.relocation`)

    @property
    def final(self) -> np.ndarray:
        last: np.ndarray = self.positions[-1]
        return last


class AlphaCvt:
    """Centralized alpha-CVT (Alg. 2) on one domain; reusable for several runs."""

    def __init__(self, domain: CoverageDomain, config: AcvtConfig | None = None) -> None:
        self.config = config or AcvtConfig()
        self.cells = MassCells(domain)

    def cvt_step(self, positions: np.ndarray, reach: np.ndarray | None,
                 movers: np.ndarray | None = None) -> np.ndarray:
        """One iCVT + projection step (Eq. 1/12/15/17, 7, 8) of the agents ``movers`` (bool
        mask; all by default) on the partition among themselves; others keep their place.
        An agent with an empty cell keeps its position as virtual target (then projected)."""
        return cvt_step(self.cells, self.config.cells, positions, reach, movers,
                        self.config.projection)

    def evaluate(self, positions: np.ndarray,
                 reach: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, float]:
        """``(labels (N,), masses (k,), metric)`` of the partition at ``positions``."""
        return team_metric(self.cells, self.config.cells, positions, reach)

    def run(self, starts: np.ndarray, speeds: np.ndarray | None = None) -> AcvtResult:
        """Alg. 2 from ``starts (k, 2)`` [m]. ``speeds (k,)`` [m/s] make the agents
        heterogeneous (Eq. 16-18, reach R_i = v_max,i * 1 s); None = homogeneous."""
        cfg = self.config
        P = np.asarray(starts, dtype=np.float64).reshape(-1, 2)
        k = len(P)
        if k < 1:
            raise ConfigError.at("starts", "need at least one agent", k)
        reach = None
        if speeds is not None:
            reach = np.asarray(speeds, dtype=np.float64).reshape(-1)
            if reach.shape != (k,) or not np.all(np.isfinite(reach)) or np.any(reach <= 0):
                raise ConfigError.at("speeds", f"must be {k} finite numbers > 0 [m/s]",
                                     reach.tolist())
        switch = DropoutSwitch(cfg.dropout)
        # Relocation belongs to alpha-CVT: the baselines (dropout off) run without it.
        relocate = cfg.relocation.enabled and cfg.dropout.enabled and cfg.projection
        P = self.cvt_step(P, reach)  # lines 2-3
        labels, masses, metric = self.evaluate(P, reach)
        switch.update(metric)
        history, metrics, greedy_counts = [P.copy()], [metric], []
        dropout_iterations = relocations = 0
        converged = False
        settled = False  # the last iteration ended settled, with the dropout off
        for _ in range(cfg.max_iterations):
            greedy = np.zeros(k, dtype=bool)
            if settled:
                # Settled without the dropout: relocate a light agent if that is predicted
                # to lower the metric (this iteration moves only it), else the run is done.
                move = None
                if relocate and relocations < cfg.relocation.max_moves:
                    move = best_relocation(self.cells, cfg.cells, P, reach, cfg.relocation)
                if move is None:
                    converged = True
                    break
                relocations += 1
                P = P.copy()
                P[list(move.agents)] = move.points
                labels, masses, metric = self.evaluate(P, reach)
                history.append(P.copy())
                metrics.append(metric)
                greedy_counts.append(0)
                settled = False
                continue
            if switch.active:
                weighed = masses if reach is None else normalized_masses(masses, reach)
                greedy = greedy_mask(weighed, cfg.dropout.drop_factor)
                if greedy.any():  # Alg. 1: CVT of the normal agents without the greedy ones
                    dropout_iterations += 1
                    P = self.cvt_step(P, reach, ~greedy)
                else:
                    switch.stop()
            new = self.cvt_step(P, reach)  # reinsertion: CVT of all (lines 9-10)
            step = float(np.hypot(*(new - history[-1]).T).max())
            P = new
            labels, masses, metric = self.evaluate(P, reach)  # line 11
            switch.update(metric)
            history.append(P.copy())
            metrics.append(metric)
            greedy_counts.append(int(greedy.sum()))
            settled = not switch.active and not greedy.any() and step < cfg.tolerance
        else:
            converged = settled
        return AcvtResult(np.array(history), np.array(metrics), np.array(greedy_counts),
                          dropout_iterations, len(greedy_counts), converged, labels, masses,
                          relocations)
