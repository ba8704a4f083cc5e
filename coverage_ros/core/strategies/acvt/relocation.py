"""Relocation: the lightest agent reinserted into the heaviest cell, kept only where the team's
metric is predicted to fall (this project's addition to Lee & Lee's alpha-CVT).

Why: alpha-CVT's dropout and reinsertion (Alg. 1-2) decides how many agents each disjoint
target gets while its dropout phase runs, and that phase ends on a filtered Delta I (Eq. 10),
whatever the split is then. From some starts it ends with the wrong split - e.g. one normal
agent left among the greedy ones of an under-served target owns all of it once they are dropped,
so nobody moves - or with a CVT inside one target whose cells are unequal; then iCVT +
projection keeps that local minimum for good.

What: once the dropout is off and the team has settled (every agent at its goal), each of the
few agents of least (normalised) mass j tries moving to the point of each of the heaviest cells
h farthest from that cell's agent (the part of the cell its owner covers worst) and, in a team
of one reach, to the point halfway to that agent (:func:`nudge_point`: one target's CVTs differ
in how equal their cells are, and a step into a heavy neighbour's cell lets the team settle
into a nearby, more equal one, where a far point rebuilds the same; a team of mixed reaches
keeps its few plans for farther moves), and the team's iCVT + projection is run forward to
convergence from there (:func:`.prediction.settle`). The best of these predictions is taken
if its metric (I, I^L or I^H) is below the team's own future - the CVT
it reaches without a move - by at least ``margin`` (``mixed_margin`` in a team of mixed
reaches); otherwise nothing moves. (Weighed against the present metric instead, a team whose
live positions jitter about its CVT, or that still crawls towards it, would see a gain in a
move that only rebuilds it.) It is the dropout idea one step further: instead of the greedy
agents stepping aside, an idle one is reinserted where it is missing.

In a team of mixed reaches one agent at a time is not enough: the compositions of the targets
that give each its share of sum R^2 can be several single moves apart, each of which raises
the metric (:mod:`.exchange`). There the relocation also predicts *exchanges* (several agents
change targets at once) and *swaps* (two agents of different reach in one target trade
places); their guard is the reach-weighted coverage cost, which they may raise by
``exchange_slack`` - as may a single agent's move into another target (where the targets'
densities differ, H prefers another split than equal masses); a move within a target may not
raise it by more than ``energy_slack`` (0.2 %: the L and disc's CVTs of more equal cells
can cost that much more H).

A team of mixed reaches can also *crawl*: Lloyd's steps shrink below a live robot's goal
tolerance, so live it stops, far from the CVT they lead to. Where the team's own future lies
farther than :data:`JUMP_DISTANCE` from an agent and below the present metric by ``margin``,
the *jump* - those agents straight to their places in it - is a candidate too (a plan,
:mod:`.plans`).

Every move taken is predicted to end ``margin`` or more below the team's own future (a jump:
below its present), and a run makes at most
``max_moves`` of them (a decentralized team of mixed reaches, at most
:data:`~coverage_ros.core.strategies.acvt.strategy.MAX_PLANS` plans): a team never relocates
for ever, even where a prediction and the live team part ways.

Both forms use it: the centralized :class:`~coverage_ros.core.strategies.acvt.dropout.AlphaCvt`
relocates between its iterations. In the decentralized strategy the few lightest robots of a
settled neighbourhood of one reach predict with their neighbours' published positions - all
finding the same relocation - and the one it names drives to its point; in a team of mixed
reaches only the robot of lowest id heard predicts, and publishes the move as a plan that the
robots it names carry out (:mod:`.plans`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.strategies.acvt.cells import CellSpec, MassCells, normalized_masses
from coverage_ros.core.strategies.acvt.exchange import agent_regions, exchanges, swaps
from coverage_ros.core.strategies.acvt.prediction import coverage_energy, settle, team_metric
from coverage_ros.errors import ConfigError

#: Fewest the predicted metric must fall by for a relocation to be made (absolute; I is a
#: share of the mean mass, so this is 0.2 % of it): small enough for a single move out of a
#: CVT of slightly unequal cells. Predictions are weighed against the team's own future
#: (settled alike), so live jitter does not show as a gain.
DEFAULT_MARGIN = 0.002
#: :data:`DEFAULT_MARGIN` in a team of mixed reaches: its moves are exchanges and swaps of
#: robots of different speeds, which the live team follows less closely than the prediction.
DEFAULT_MIXED_MARGIN = 0.005
#: Heaviest cells tried for each agent that may move.
DEFAULT_CANDIDATES = 3
#: Lightest agents that may move (with mixed speeds the best agent to move is not always the
#: lightest: a slow one may be missing where a fast one is lightest).
DEFAULT_MOVERS = 3
#: iCVT + projection steps of a prediction (the arena scenarios converge in 15-40).
DEFAULT_HORIZON = 60
#: Exchanges of several agents between targets tried in a heterogeneous team (:mod:`.exchange`).
DEFAULT_EXCHANGES = 4
#: Share by which the reach-weighted H may rise with an exchange or a move into another target
#: (a change of the split between targets): compositions that give every target its share of
#: R^2 can differ in H either way, and H weighs a target's agents by its density, so it may
#: prefer another split than equal masses.
DEFAULT_EXCHANGE_SLACK = 0.1
#: Updates of a settled team over which its metric must not fall by ``margin`` before a robot
#: predicts a relocation from it (:class:`MetricLevel`).
DEFAULT_LEVEL_WINDOW = 3
#: [m] a team of mixed reaches whose predicted CVT lies farther than this from an agent's
#: place is sent there (the jump of :func:`best_relocation`).
JUMP_DISTANCE = 0.5
#: iCVT + projection steps of the team's own future (a crawl can take a hundred).
JUMP_HORIZON = 240
#: Share of ``tolerance`` at which the team's own future has converged (a crawl's steps are
#: 1-3 cm: at the predictions' 1 cm it would stop a few steps in).
JUMP_TOLERANCE = 0.1
#: Swaps (two agents of different reach in one target trade places) tried per exchange.
SWAPS_PER_EXCHANGE = 3


@dataclass(frozen=True)
class RelocationConfig:
    enabled: bool = True
    candidates: int = DEFAULT_CANDIDATES  # heaviest cells tried for each agent that may move
    movers: int = DEFAULT_MOVERS  # lightest agents that may move
    margin: float = DEFAULT_MARGIN  # the predicted metric must fall by at least this
    #: the same in a team of mixed reaches (see :data:`DEFAULT_MIXED_MARGIN`)
    mixed_margin: float = DEFAULT_MIXED_MARGIN
    horizon: int = DEFAULT_HORIZON  # iCVT + projection steps of a prediction
    tolerance: float = 0.01  # [m] a prediction has converged when no agent moves farther
    energy_slack: float = 0.002  # share by which Eq. 2's H may rise with a move in a target
    max_moves: int = 20  # relocations of one run (centralized) or one robot (decentralized)
    exchanges: int = DEFAULT_EXCHANGES  # several-agent moves tried with mixed reaches (0: none)
    #: share H may rise with an exchange or a move into another target
    exchange_slack: float = DEFAULT_EXCHANGE_SLACK

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool | np.bool_):
            raise ConfigError.at("relocate", "must be true or false", self.enabled)
        for name in ("candidates", "movers", "horizon", "max_moves"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError.at(f"relocation.{name}", "must be an integer >= 1", value)
        if isinstance(self.exchanges, bool) or not isinstance(self.exchanges, int) \
                or self.exchanges < 0:
            raise ConfigError.at("relocation.exchanges", "must be an integer >= 0",
                                 self.exchanges)
        for name in ("margin", "mixed_margin", "tolerance"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError.at(f"relocation.{name}", "must be a finite number > 0", value)
        for name in ("energy_slack", "exchange_slack"):
            slack = getattr(self, name)
            if not (isinstance(slack, int | float) and math.isfinite(slack) and slack >= 0):
                raise ConfigError.at(f"relocation.{name}", "must be a finite number >= 0",
                                     slack)

    def margin_for(self, reach: np.ndarray | None) -> float:
        """The margin of a team whose reaches are ``reach`` (None: all equal)."""
        return self.margin if reach is None else self.mixed_margin


@dataclass(frozen=True)
class Relocation:
    """A relocation worth making: agents ``agents`` go to ``points`` - one light agent into a
    heavy cell, or several agents of a heterogeneous team changing targets (:mod:`.exchange`)."""

    agents: tuple[int, ...]  # indices of the relocated agents
    into: tuple[int, ...]  # for each, the agent whose cell it enters
    points: np.ndarray  # (m, 2) [m] where they go
    metric_before: float  # the team's metric when it was predicted
    metric_after: float  # predicted, after the team re-converges

    def point_of(self, agent: int) -> np.ndarray | None:
        """``(2,)`` [m]: where ``agent`` goes, or None when it is not one of the moved."""
        return self.points[self.agents.index(agent)].copy() if agent in self.agents else None


class MetricLevel:
    """Whether a settled team's metric has stopped falling: among the last ``window`` + 1
    values recorded since the last :meth:`reset`, the newest is not below the oldest by
    ``margin`` or more. A robot near its goal counts as settled while its neighbourhood may
    still be converging (each step a few centimetres, after a relocation for many updates); a
    relocation predicted from there is weighed against a metric that the team is about to
    beat on its own, and plans made one after the other in that state spend a team's plans on
    moves that overlap."""

    def __init__(self, window: int, margin: float) -> None:
        if isinstance(window, bool) or not isinstance(window, int) or window < 1:
            raise ConfigError.at("relocation.level_window", "must be an integer >= 1", window)
        self.margin = float(margin)
        self._values: deque[float] = deque(maxlen=window + 1)

    def record(self, value: float) -> bool:
        """Add ``value``; True once the metric has levelled off (see the class)."""
        self._values.append(float(value))
        return (len(self._values) == self._values.maxlen
                and self._values[-1] > self._values[0] - self.margin)

    def reset(self) -> None:
        """The team is moving (a neighbour is unsettled or relocating): start over."""
        self._values.clear()


def insertion_point(cells: MassCells, labels: np.ndarray, positions: np.ndarray,
                    owner: int) -> np.ndarray | None:
    """``(2,)`` [m]: the mass cell of ``owner``'s cell farthest from ``owner`` (None for an
    empty cell)."""
    own = np.flatnonzero(labels == owner)
    if len(own) == 0:
        return None
    d2 = ((cells.xy[own] - positions[owner]) ** 2).sum(axis=1)
    point: np.ndarray = cells.xy[own[int(np.argmax(d2))]].copy()
    return point


def nudge_point(cells: MassCells, positions: np.ndarray, agent: int, owner: int) -> np.ndarray:
    """``(2,)`` [m]: halfway from ``agent`` to ``owner`` (projected onto rho > 0): a light
    agent stepping into a heavy neighbour's cell, so that the team settles into a nearby CVT
    rather than rebuilding one around a far point."""
    P = np.asarray(positions, dtype=np.float64)
    point: np.ndarray = cells.project((0.5 * (P[agent] + P[owner]))[None])[0]
    return point


def movers(masses: np.ndarray, reach: np.ndarray | None, count: int) -> list[int]:
    """The ``count`` agents of least (reach-normalised) mass, lightest first (ties: the lowest
    index) - the agents :func:`best_relocation` may move."""
    weighed = masses if reach is None else normalized_masses(masses, reach)
    return [int(j) for j in np.argsort(weighed, kind="stable")[:count]]


def swap_count(config: RelocationConfig) -> int:
    """Swaps tried with ``config`` (:data:`SWAPS_PER_EXCHANGE` per exchange)."""
    return SWAPS_PER_EXCHANGE * config.exchanges


def _best_swap(cells: MassCells, spec: CellSpec, P: np.ndarray, reach: np.ndarray,
               labels: np.ndarray, masses: np.ndarray, metric: float,
               config: RelocationConfig) -> tuple[np.ndarray, np.ndarray, float]:
    """``(positions, labels, metric)`` after the best of the swaps at the settled ``P``, if
    one lowers ``metric``; else those of ``P``."""
    best = (P, labels, metric)
    for e in swaps(cells, labels, masses, P, reach, swap_count(config)):
        Q = P.copy()
        Q[list(e.agents)] = e.points
        Q = settle(cells, spec, Q, reach, config.horizon, config.tolerance)
        labels_q, _, after = team_metric(cells, spec, Q, reach)
        if after < best[2]:
            best = (Q, labels_q, after)
    return best


def own_future(cells: MassCells, spec: CellSpec, positions: np.ndarray,
               reach: np.ndarray | None, config: RelocationConfig) -> tuple[np.ndarray, float]:
    """``(positions (k, 2) [m], metric)`` of the CVT a team at ``positions`` reaches without a
    move (iCVT + projection until no agent moves farther than a tenth of the predictions'
    tolerance, :data:`JUMP_HORIZON` steps at most): what a relocation is weighed against."""
    still = settle(cells, spec, np.asarray(positions, dtype=np.float64), reach, JUMP_HORIZON,
                   JUMP_TOLERANCE * config.tolerance)
    return still, team_metric(cells, spec, still, reach)[2]


def way_back(best_future: tuple[float, np.ndarray, np.ndarray] | None, metric: float,
             positions: np.ndarray, row_ids: np.ndarray, margin: float,
             tolerance: float) -> Relocation | None:
    """The last plan of a team of mixed reaches whose planner has spent its plans: back to the
    best CVT it foresaw (``best_future``: the lowest :func:`own_future` of the settled teams it
    predicted from, this one's included - its metric, positions and robot ids), if the team,
    settled at ``positions`` (robot ids ``row_ids``), is ``margin`` or more above it
    (``metric``), with the same robots in view. A plan's prediction can part ways with the
    live team (an exchange that a one-update lag in the neighbours' positions settles into
    another CVT, or a crawl towards a CVT that stops where the robots' steps fall below their
    tolerance); without a way back the team keeps the worse end for good. The robots farther
    than ``tolerance`` [m] from their places there go."""
    if best_future is None:
        return None
    best, places, ids = best_future
    if best > metric - margin or not np.array_equal(np.sort(ids), np.sort(row_ids)):
        return None
    Q = places[np.argsort(ids)][np.argsort(np.argsort(row_ids))]  # (in this view's rows)
    far = np.flatnonzero(np.hypot(*(Q - positions).T) > tolerance)
    if len(far) == 0:
        return None
    agents = tuple(int(a) for a in far)
    return Relocation(agents, agents, Q[far], metric, best)


def best_relocation(cells: MassCells, spec: CellSpec, positions: np.ndarray,
                    reach: np.ndarray | None, config: RelocationConfig,
                    future: tuple[np.ndarray, float] | None = None) -> Relocation | None:
    """Of the relocations of each of the ``movers`` lightest agents into each of the
    ``candidates`` heaviest cells - and, in a team of mixed reaches on separate targets, the
    ``exchanges`` best several-agent exchanges between targets (:mod:`.exchange`) - the one
    that lowers the predicted metric most, if by at least ``margin``; else None.
    ``positions (k, 2)`` [m] should be a settled configuration. Deterministic: robots that
    know the same positions find the same relocation. ``future``: :func:`own_future` of
    ``positions``, if it was found already."""
    P = np.asarray(positions, dtype=np.float64)
    if len(P) < 2:
        return None
    margin = config.margin_for(reach)
    labels, masses, now = team_metric(cells, spec, P, reach)
    # Weighed against the team's own future, the CVT it reaches without a move: live
    # positions jitter about it (a move that rebuilds it would look like a gain over ``now``),
    # and a team can crawl towards it for a hundred updates (see below).
    still, before = own_future(cells, spec, P, reach, config) if future is None else future
    energy = coverage_energy(cells, cells.labels(still, reach, spec), still, reach)
    weighed = masses if reach is None else normalized_masses(masses, reach)
    heavy = [int(h) for h in np.argsort(-weighed, kind="stable")]
    # A move into another target changes the split between targets, which sets each
    # target's mass per agent; H and I part ways there where the targets' densities differ
    # (Fig. 4c: H prefers 4 + 6 agents, I 5 + 5), so it may raise H as an exchange may.
    target = agent_regions(cells, labels, len(P)) if cells.regions > 1 else \
        np.full(len(P), -1)
    # (agents, the cells they enter, their points, H's allowed rise, look a swap ahead)
    tries: list[tuple[tuple[int, ...], tuple[int, ...], np.ndarray, float, bool]] = []
    for j in movers(masses, reach, config.movers):
        for h in [h for h in heavy if h != j][:config.candidates]:
            across = target[j] >= 0 and target[h] >= 0 and target[j] != target[h]
            slack = config.exchange_slack if across else config.energy_slack
            point = insertion_point(cells, labels, P, h)
            if point is not None:
                tries.append(((j,), (h,), point[None], slack, False))
            if reach is None:
                tries.append(((j,), (h,), nudge_point(cells, P, j, h)[None], slack, False))
    mixed = reach is not None and config.exchanges > 0 and not spec.visibility
    if mixed and reach is not None:
        tries += [(e.agents, e.into, e.points, config.exchange_slack, True)
                  for e in exchanges(cells, labels, masses, P, reach, config.exchanges)]
        tries += [(e.agents, e.into, e.points, config.exchange_slack, False)
                  for e in swaps(cells, labels, masses, P, reach, swap_count(config))]
    best: Relocation | None = None
    far = np.flatnonzero(np.hypot(*(still - P).T) > JUMP_DISTANCE)
    if mixed and len(far) and before <= now - margin:
        # The jump past a crawl (module docstring): a plan (:mod:`.plans`) sends the robots
        # to the CVT at once.
        agents = tuple(int(a) for a in far)
        best = Relocation(agents, agents, still[far], now, before)
    for agents, into, points, slack, ahead in tries:
        Q = P.copy()
        Q[list(agents)] = points
        Q = settle(cells, spec, Q, reach, config.horizon, config.tolerance)
        labels_q, masses_q, after = team_metric(cells, spec, Q, reach)
        if ahead and reach is not None:
            # An exchange lands its movers anywhere in their new target; the swap that best
            # follows it is part of its prediction (and is found again once it has settled).
            Q, labels_q, after = _best_swap(cells, spec, Q, reach, labels_q, masses_q, after,
                                            config)
        if after > before - margin or (best is not None and after >= best.metric_after):
            continue
        # Never at the cost of coverage: a move that only trades the masses' balance for
        # a worse covered area (Eq. 2) is not made (on one connected area with a uniform
        # density a lower I can mean a higher H).
        if coverage_energy(cells, labels_q, Q, reach) > energy * (1.0 + slack):
            continue
        best = Relocation(agents, into, points, now, after)
    return best
