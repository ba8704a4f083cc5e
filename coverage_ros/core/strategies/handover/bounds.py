"""The costs of a handover: two each computed by one robot over its own cell, and a joint one.

A handover moves robot i out of its cell V_i into a neighbour j's cell V_j. Every other
generator stays, so after the move each grid cell may keep any owner; the geodesic power
Voronoi cells minimize H over all assignments of grid cells to generators, so the cost of any
one assignment bounds the new H from above (equal power weights). The assignment used:

* V_i and the cells of i's bordering neighbours go to those neighbours, which take a few
  Lloyd steps in that region while every other generator stays: :func:`removal_increase`
  (robot i, from its neighbours' generators, which it tessellates anyway) is the region's cost
  after minus before;
* V_j is split between j (staying where it is) and a second generator s placed by a few
  Lloyd steps inside V_j: :func:`.split.split_offer` (robot j) is ``H_j - sum_{q in V_j}
  (min(g_j(q), g_s(q))^2 - R^2) w dA`` and the point s.

When the two regions share no node (j's cell is not among the region's movable ones: a
bordering j is held ``fixed``), ``removal_increase(i) - split_gain(j)`` bounds the change of H
from above for i at s and i's movable neighbours at the positions the removal returns. The
robots then run generalized Lloyd from i's move, not from those positions: the bound says that
a configuration that much better lies next to the one the move makes, which Lloyd's descent
reaches in the cases tested (the move is a claim backed by a configuration, not a proof about
where Lloyd ends).

Where no pair's bound suffices - leaving V_i costs more than splitting V_j saves while the
other neighbours stay - :func:`joint_change` (robot i, from every generator it hears) lets
every generator whose cell touches V_i or V_j take the Lloyd steps together with s, and
compares with the same steps without the move; with wider rings, a move that pays so is
checked by the team's own generalized Lloyd descent from it (:func:`descent_change`).
Distances are the tessellation's own (:func:`~coverage_ros.core.geodesic.tessellation.
source_row` sources on the whole-domain graph), searched only as far as the cell needs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import binary_dilation

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.whole_map import nearest
from coverage_ros.core.offline.geodesic_team import team_cells

#: Searches reach this many longest graph edges beyond the bound they need.
SLACK_EDGES = 4.0
#: Growth of a removal search radius that left nodes of the cell unreached (then unlimited).
GROWTH = 2.0
#: Steps of the team's own descent that check a wider ring's move (:func:`descent_change`);
#: from a move across a 30 x 50 m warehouse the team settles within about 15.
DESCENT_STEPS = 30
#: Halvings of a descent step that would raise H before the descent counts as stalled.
DESCENT_HALVINGS = 4


def node_points(domain: CoverageDomain, nodes: np.ndarray) -> np.ndarray:
    """``(n, 2)`` [m] map-frame centres of grid nodes ``nodes`` (row * W + col)."""
    W = domain.shape[1]
    rows, cols = np.divmod(np.asarray(nodes, dtype=np.int64), W)
    return domain.to_map(np.column_stack([cols + 0.5, rows + 0.5]))


@dataclass(frozen=True)
class Removal:
    """What the own generator's leaving costs at most."""

    increase: float  # rise of the region's cost, units of H (inf: not computable)
    movers: tuple[int, ...]  # indices of the generators that take Lloyd steps
    positions: np.ndarray  # (len(movers), 2) [m] where they stand at that cost


#: Searches from every generator a robot knows, by limit (chart units): the same for each
#: removal bound of one configuration, whichever neighbour it holds fixed.
Tessellations = dict[float, tuple[np.ndarray, np.ndarray]]


def removal_increase(domain: CoverageDomain, generators: np.ndarray, weight: float,
                     bordering: Sequence[int], fixed: Sequence[int], cell_radius: float,
                     steps: int, method: str = "auto",
                     tessellations: Tessellations | None = None) -> Removal:
    """How much H would rise at most if generator 0 of ``generators (m, 2)`` [m] (the own;
    the others: every neighbour known, all of power weight ``weight``) left its cell.

    The own cell and the cells of its ``bordering`` neighbours (indices into ``generators``)
    but ``fixed`` ones form a region U; U's nodes are assigned to the nearest of those
    neighbours and the ``fixed`` ones, the movable neighbours taking ``steps`` Lloyd steps in U
    (each to its part's node nearest the part's mass centroid), the least cost kept. Nodes
    outside U keep their owners, so with the movable neighbours at the returned positions H
    rises by at most the returned increase (inf without movable or fixed neighbours, or if a
    node of U is out of their reach). ``tessellations`` keeps searches for the next bound of
    the same ``generators``."""
    gens = np.asarray(generators, dtype=np.float64).reshape(-1, 2)
    movers = [k for k in bordering if k not in fixed]
    keep = list(fixed)
    if not movers and not keep:
        return Removal(math.inf, (), np.zeros((0, 2)))
    wdA = domain.mass_element.ravel()
    slack = SLACK_EDGES * domain.graph.max_edge_cost
    limit = 4.0 * cell_radius + slack
    own = [0, *movers]
    known = {} if tessellations is None else tessellations

    def search(limit: float) -> tuple[np.ndarray, np.ndarray]:
        if limit not in known:
            known[limit] = nearest(domain, gens, limit, method)
        return known[limit]

    for _ in range(3):
        d, label = search(limit)
        # a cell whose nodes all lie closer than the limit by an edge is whole
        near = np.isin(label, own)
        if float(d[near].max(initial=0.0)) < limit - domain.graph.max_edge_cost:
            break
        limit *= GROWTH
    else:
        d, label = search(math.inf)
        near = np.isin(label, own)
    U = np.flatnonzero(near)
    before = float(((d[U] ** 2 - weight ** 2) * wdA[U]).sum())
    best, at = _lloyd_in(domain, U, gens[movers], gens[keep], weight, steps,
                         GROWTH * limit, method)
    return Removal(best - before, tuple(movers), at)


def _lloyd_in(domain: CoverageDomain, U: np.ndarray, movers: np.ndarray, fixed: np.ndarray,
              weight: float, steps: int, limit: float, method: str,
              whole: bool = False, stand: dict[float, np.ndarray] | None = None
              ) -> tuple[float, np.ndarray]:
    """The least cost of the nodes ``U`` each assigned to the nearest of ``movers (a, 2)``
    and ``fixed (b, 2)`` [m] over ``steps`` Lloyd steps of the movers (each to its part's
    node nearest the part's mass centroid), and where the movers stood then (inf if a node
    of U is out of reach within ``limit``; with ``whole``, a step that leaves a node of U
    unreached searches again without limit).

    The nearest of all is the nearer of the nearest mover and the nearest fixed generator
    (a search's distances are the least over its sources), so the fixed generators are
    searched once (kept by limit in ``stand``, for the next steps in U with the same fixed
    generators) and each step searches from the movers alone, which reach no farther than
    ``limit`` around U instead of the whole map."""
    wdA = domain.mass_element.ravel()
    w, pts = wdA[U], node_points(domain, U)
    pos = np.array(movers, dtype=np.float64).reshape(-1, 2)
    fixed = np.asarray(fixed, dtype=np.float64).reshape(-1, 2)
    stand = {} if stand is None else stand

    def near(limit: float) -> tuple[np.ndarray, np.ndarray]:
        if limit not in stand:
            stand[limit] = nearest(domain, fixed, limit, method)[0][U] if len(fixed) \
                else np.full(len(U), math.inf)
        gf = stand[limit]
        gm, lm = nearest(domain, pos, limit, method)
        gm, lm = gm[U], lm[U]
        mine = gm <= gf
        return np.where(mine, gm, gf), np.where(mine, lm, -1)

    best, at = math.inf, pos.copy()
    for step in range(steps + 1):
        g, lab = near(limit)
        if whole and math.isfinite(limit) and not np.all(np.isfinite(g)):
            # distances within the limit are exact: only an unreached node needs the rest
            g, lab = near(math.inf)
        if not np.all(np.isfinite(g)):
            break
        value = float(((g * g - weight ** 2) * w).sum())
        if value < best:
            best, at = value, pos.copy()
        if step == steps:
            break
        last = pos.copy()
        # each mover's part in index order, as a mask would select it (a stable sort)
        by_label = np.argsort(lab.astype(np.int32), kind="stable")
        bounds = np.searchsorted(lab[by_label], np.arange(len(pos) + 1))
        for k in range(len(pos)):
            part = by_label[bounds[k]:bounds[k + 1]]
            wp, pp = w[part], pts[part]
            m = float(wp.sum())
            if m > 0:
                centroid = (pp * wp[:, None]).sum(axis=0) / m
                pos[k] = pp[int(np.argmin(np.hypot(*(pp - centroid).T)))]
        if np.array_equal(pos, last):
            break  # a fixed point: every further step gives the same cost
    return best, at


@dataclass(frozen=True)
class Known:
    """The tessellation of the generators one robot knows (its own first), whole-map."""

    generators: np.ndarray  # (m, 2) [m]
    distances: np.ndarray  # (H * W,) chart units to the nearest generator (inf: unreached)
    labels: np.ndarray  # (H * W,) index of that generator (-1: unreached)
    stay: dict[tuple[int, ...], float] = field(default_factory=dict)  # U's cost reached
    # without a move, per group of movers (units of H)
    descended: dict[tuple[int, ...], float] = field(default_factory=dict)  # H the team's
    # own descent reaches without a move, per group of movers (:func:`descent_change`)
    standing: dict[tuple[int, ...], dict[float, np.ndarray]] = field(default_factory=dict)
    # distances over U from the generators that stay, per group of movers, by search limit


def known_cells(domain: CoverageDomain, generators: np.ndarray, method: str = "auto") -> Known:
    """The cells of ``generators (m, 2)`` [m] (equal power weights) over the whole map."""
    gens = np.asarray(generators, dtype=np.float64).reshape(-1, 2)
    d, label = nearest(domain, gens, math.inf, method)
    return Known(gens, d, label)


def joint_change(domain: CoverageDomain, known: Known, weight: float, target: int,
                 point: np.ndarray, steps: int, method: str = "auto",
                 rings: int = 1, max_step: float = 0.0) -> Removal:
    """How much lower H gets at least if generator 0 of ``known`` (the own) moved to
    ``point`` [m] in the cell of generator ``target``, the neighbours re-spreading, than if it
    stayed: negative for a move that pays.

    U is the union of the own cell, the target's and every cell that touches either (8 grid
    neighbours); with ``rings`` k > 1, grown k - 1 times more by the cells touching it (a robot
    shut in a corner whose one neighbour cannot take its cell alone: the shift runs through the
    team), and then a bound only where every other mover ends in its own cell or the own one
    (:func:`_shifts_within`, else inf). Every generator with a cell in U but the own, and one
    at ``point``, takes ``steps`` Lloyd steps in U, every other generator staying where it is.
    Nodes outside U keep their owners, which do not move, so the least cost of U seen bounds H
    from above for the movers at the positions reached. The same steps without the move (the
    own generator among the movers, none at ``point``) give what staying reaches; the change is
    the one bound minus the other (inf if a node of U is out of reach), returned with the
    movers (indices into ``known.generators``; the last, -1, the one at ``point``, which is the
    own generator moved) and where they stand. A wider ring's move that pays so, and with
    ``max_step`` > 0 [m] any move that pays so, is priced again by the team's own descent from
    it (:func:`descent_change`, its steps at most ``max_step`` long), which is returned
    instead: the bound's Euclidean centroid steps may carry a robot through a doorway that a
    live robot's short steps do not pass."""
    W = domain.shape[1]
    labels = known.labels.reshape(-1, W)
    members = {0, target}
    for _ in range(max(1, rings)):
        core = binary_dilation(np.isin(labels, sorted(members)),
                               structure=np.ones((3, 3), bool))
        members |= {int(k) for k in np.unique(labels[core]) if k >= 0}
    group = sorted(members)
    U = np.flatnonzero(np.isin(known.labels, group))
    movers = [k for k in group if k != 0]
    fixed = known.generators[[k for k in range(len(known.generators)) if k not in group]]
    # searches reach GROWTH times U's farthest node now (exact within; beyond: again, whole)
    limit = GROWTH * float(known.distances[U].max(initial=0.0)) \
        + SLACK_EDGES * domain.graph.max_edge_cost
    stand = known.standing.setdefault(tuple(group), {})
    if tuple(group) not in known.stay:
        known.stay[tuple(group)] = _lloyd_in(domain, U, known.generators[group], fixed, weight,
                                             steps, limit, method, whole=True, stand=stand)[0]
    stay = known.stay[tuple(group)]
    if not math.isfinite(stay):
        return Removal(math.inf, (), np.zeros((0, 2)))
    start = np.vstack([known.generators[movers], np.asarray(point, dtype=np.float64)[None]])
    moved, at = _lloyd_in(domain, U, start, fixed, weight, steps, limit, method, whole=True,
                          stand=stand)
    if rings > 1 and not _shifts_within(domain, known.labels, movers, at[:-1]):
        return Removal(math.inf, (), np.zeros((0, 2)))
    if (rings > 1 or max_step > 0) and moved < stay:
        return descent_change(domain, known, weight, movers, point, method,
                              max_step=max_step)
    return Removal(moved - stay, (*movers, -1), at)


def descent_change(domain: CoverageDomain, known: Known, weight: float,
                   movers: Sequence[int], point: np.ndarray, method: str = "auto",
                   steps: int = DESCENT_STEPS, enough: float = math.inf,
                   max_step: float = 0.0) -> Removal:
    """How much lower H gets at least if generator 0 of ``known`` moved to ``point`` [m] and
    ``movers`` (indices into ``known.generators``) then followed the team's own generalized
    Lloyd descent for ``steps`` steps (:func:`_descent`), every other generator staying, than
    if they all descended from where they stand: negative for a move that pays, returned with
    the movers (the last, -1, the own generator moved) and where they stand then.

    A wider ring's bound names a configuration that lower, but reached by Euclidean centroid
    steps that may jump a robot through a doorway into another room; the robots' own steps
    follow the geodesic gradient and may settle elsewhere (a robot left its room for the
    vacated one in the bound, and stayed in it when the team descended from the move).
    This is where they go. With H non-increasing along both descents, H at the returned
    configuration is at most H now plus the change.

    With a finite ``enough`` (units of H) the descent from the move stops once its change is
    below ``-enough``: a move that pays that much (further steps only lower H), known in a
    fraction of the steps. (A descent that does not pay runs on: it may creep for steps, then
    drop as a robot passes a doorway.)

    With ``max_step`` > 0 [m] every step of either descent is at most that long per robot, and
    ``steps`` more are allowed by how many such steps cross the map: live robots move that far
    between coverage updates (v_max / control_rate), and their descent then follows the
    gradient closely; whole steps may carry a robot through a doorway that the live robot,
    re-tessellated every few cm, does not pass (``known``'s cache of the descent without a move
    is for one ``max_step``)."""
    group = [0, *movers]
    if max_step > 0:
        span = float(np.hypot(*domain.shape)) * domain.resolution  # [m] the map's diagonal
        steps += math.ceil(span / max_step)
    if tuple(group) not in known.descended:
        known.descended[tuple(group)] = _descent(domain, known.generators, group, weight,
                                                 steps, method, max_step=max_step)[1]
    stay = known.descended[tuple(group)]
    start = known.generators.copy()
    start[0] = np.asarray(point, dtype=np.float64)
    at, moved = _descent(domain, start, group, weight, steps, method, stay - enough, max_step)
    return Removal(moved - stay, (*movers, -1), np.vstack([at[list(movers)], at[0][None]]))


def _descent(domain: CoverageDomain, generators: np.ndarray, group: Sequence[int],
             weight: float, steps: int, method: str, target: float = -math.inf,
             max_step: float = 0.0) -> tuple[np.ndarray, float]:
    """Where ``group`` (indices of ``generators (m, 2)`` [m]) ends after ``steps`` steps of
    generalized Lloyd (every robot's reachable goal, :func:`~coverage_ros.core.offline.
    geodesic_team.team_cells`), the others staying, and H there. A step that would raise H is
    halved (a generalized Lloyd step may overshoot) up to :data:`DESCENT_HALVINGS` times, else
    the descent stops; it stops too once no robot's step is longer than half a grid cell, or
    once H is below ``target``. With ``max_step`` > 0 [m] each robot's step is cut to at most
    that long."""
    P = np.array(generators, dtype=np.float64).reshape(-1, 2)
    R = np.full(len(P), float(weight))
    g = np.asarray(group, dtype=np.int64)
    cells = team_cells(domain, P, R, method)
    H = float(cells.costs.sum())
    for _ in range(steps):
        if H < target:
            break
        step = cells.goals[g] - P[g]
        length = np.hypot(*step.T)
        if float(length.max(initial=0.0)) < 0.5 * domain.resolution:
            break
        if max_step > 0:
            step = step * np.minimum(1.0, max_step / np.maximum(length, 1e-12))[:, None]
        for _ in range(DESCENT_HALVINGS + 1):
            Q = P.copy()
            Q[g] = P[g] + step
            if all(domain.is_free_point(q) for q in Q[g]):
                trial = team_cells(domain, Q, R, method)
                if float(trial.costs.sum()) <= H:
                    break
            step = 0.5 * step
        else:
            break  # no step along the descent lowers H: a stall, where the robots stop too
        P, cells, H = Q, trial, float(trial.costs.sum())
    return P, H


def _shifts_within(domain: CoverageDomain, labels: np.ndarray, movers: Sequence[int],
                   positions: np.ndarray) -> bool:
    """Whether every one of ``movers`` (indices of generators) at ``positions (m, 2)`` [m]
    (node centres) lies in its own cell of ``labels`` or in generator 0's: a shift Lloyd's
    descent makes once generator 0 has left, unlike a chain of robots moving into each
    other's cells, which a wider ring's configuration may name but no robot's own steps
    reach (the team would move, re-spread into the same cells and claim again)."""
    if len(movers) == 0:
        return True
    H, W = domain.shape
    grid = np.floor(domain.to_grid(np.asarray(positions, dtype=np.float64).reshape(-1, 2)))
    nodes = np.clip(grid[:, 1], 0, H - 1).astype(np.int64) * W \
        + np.clip(grid[:, 0], 0, W - 1).astype(np.int64)
    there = labels[nodes]
    return bool(np.all((there == np.asarray(movers)) | (there == 0)))
