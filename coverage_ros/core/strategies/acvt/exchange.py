"""Exchanges: several agents of a heterogeneous team change targets at once (this project's
addition to the relocation of :mod:`coverage_ros.core.strategies.acvt.relocation`).

Why: with agents of different reach (Lee & Lee, Eqs. 16-18) a target is served in balance
when the sum of its agents' R_i^2 matches its share of the mass - and several compositions do
that. On the paper's Fig. 14 setting (5 agents at 0.4 m/s, 5 at 0.8 m/s, targets of 68 % and
32 % of the mass) both "two fast agents" and "four slow and one fast" give the small target
exactly its share, but only the first leaves cells that Lloyd can make equal. Going from one to
the other moves five agents, and every single move on the way raises I^H: the one-agent
relocation cannot get there.

What: the targets' compositions (how many agents of each reach in each target) reachable by
moving agents between two targets are ranked by how far their sums of R_i^2 are from the
targets' shares of the mass; the best few that differ from the present one by more than one
agent become candidate configurations. The agents that leave a target are its lightest of
their reach (normalised mass, Eq. 18); the ones that arrive take, in turn, the point of the
receiving target's heaviest remaining cells farthest from everything already there. The caller
(:func:`~coverage_ros.core.strategies.acvt.relocation.best_relocation`) predicts each candidate
like a single relocation and keeps the best.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.strategies.acvt.cells import MassCells, normalized_masses

#: Most distinct reaches (speed classes) and targets for which compositions are enumerated
#: (the candidates grow as the product of the class counts).
MAX_CLASSES = 3
MAX_REGIONS = 6


@dataclass(frozen=True)
class Exchange:
    """A candidate: agents ``agents`` move to ``points (m, 2)`` [m], entering the cells of
    ``into``."""

    agents: tuple[int, ...]
    into: tuple[int, ...]
    points: np.ndarray
    share_error: float  # how far the targets' sums of R^2 are from their mass shares


def agent_regions(cells: MassCells, labels: np.ndarray, k: int) -> np.ndarray:
    """``(k,) int64``: the target holding most of each agent's labelled mass (-1 for an agent
    with an empty cell or one outside every target)."""
    region = cells.region_of_cells
    ok = (labels >= 0) & (region >= 0)
    R = len(cells.region_masses)
    table = np.bincount(labels[ok] * R + region[ok], weights=cells.wdA[ok],
                        minlength=k * R).reshape(k, R)
    out: np.ndarray = np.argmax(table, axis=1)
    out[table.max(axis=1) <= 0.0] = -1
    return out


def share_error(weights: np.ndarray, region_of: np.ndarray, shares: np.ndarray) -> float:
    """Sum over targets of |(sum of the targets' agents' weights) / (all weights) - mass
    share|."""
    R = len(shares)
    ok = region_of >= 0
    held = np.bincount(region_of[ok], weights=weights[ok], minlength=R)
    return float(np.abs(held / weights.sum() - shares).sum())


def _farthest_point(cells: MassCells, own: np.ndarray, taken: np.ndarray) -> np.ndarray:
    """The mass cell of ``own`` (indices) farthest from every point of ``taken (m, 2)``."""
    d2 = ((cells.xy[own, None, :] - taken[None, :, :]) ** 2).sum(axis=2).min(axis=1)
    point: np.ndarray = cells.xy[own[int(np.argmax(d2))]].copy()
    return point


def exchanges(cells: MassCells, labels: np.ndarray, masses: np.ndarray,
              positions: np.ndarray, reach: np.ndarray, count: int) -> list[Exchange]:
    """The ``count`` candidate exchanges of least share error (ties: fewer agents moved, then
    enumeration order) at the settled configuration ``positions (k, 2)``; empty for a team of
    one reach, one target, or more than :data:`MAX_CLASSES` reaches or :data:`MAX_REGIONS`
    targets. Deterministic."""
    P = np.asarray(positions, dtype=np.float64)
    R = np.asarray(reach, dtype=np.float64)
    k = len(P)
    classes, cls = np.unique(R, return_inverse=True)
    regions = len(cells.region_masses)
    if not (2 <= len(classes) <= MAX_CLASSES and 2 <= regions <= MAX_REGIONS):
        return []
    region_of = agent_regions(cells, labels, k)
    shares = cells.region_masses / cells.region_masses.sum()
    weights = R * R  # Eq. 18: an agent's fair mass is proportional to its reachable area
    weighed = normalized_masses(masses, R)
    # Per target and class, its agents lightest first: those leave first.
    members = {(a, c): [int(i) for i in np.argsort(weighed, kind="stable")
                        if region_of[i] == a and cls[i] == c]
               for a in range(regions) for c in range(len(classes))}
    found: list[tuple[float, int, int, tuple[int, ...], tuple[int, int]]] = []
    order = 0
    for a, b in itertools.combinations(range(regions), 2):
        # x_c: agents of class c moving a -> b (negative: b -> a).
        ranges = [range(-len(members[b, c]), len(members[a, c]) + 1)
                  for c in range(len(classes))]
        for x in itertools.product(*ranges):
            moved = sum(abs(v) for v in x)
            if moved < 2:
                continue  # nothing, or one agent: the single relocation's job
            new_region = region_of.copy()
            for c, v in enumerate(x):
                src, dst, n = (a, b, v) if v > 0 else (b, a, -v)
                new_region[members[src, c][:n]] = dst
            if any(not (new_region == r).any() for r in range(regions)):
                continue  # a target left without agents
            error = share_error(weights, new_region, shares)
            found.append((error, moved, order, tuple(x), (a, b)))
            order += 1
    found.sort()
    out = []
    for error, _, _, x, (a, b) in found[:count]:
        agents, into, points = _place(cells, labels, P, weighed, members, x, a, b, region_of)
        if agents:
            out.append(Exchange(agents, into, points, error))
    return out


def swaps(cells: MassCells, labels: np.ndarray, masses: np.ndarray, positions: np.ndarray,
          reach: np.ndarray, count: int) -> list[Exchange]:
    """Candidates where two agents of different reach in one target trade places: the
    ``count`` pairs whose normalised masses (Eq. 18) differ most (ties: enumeration order).
    Lloyd's cells of mixed reaches have many equilibria (a slow agent's cell is an Apollonius
    disc inside its fast neighbours'), and which agent sits where decides how equal they end."""
    P = np.asarray(positions, dtype=np.float64)
    R = np.asarray(reach, dtype=np.float64)
    if len(np.unique(R)) < 2:
        return []
    region_of = agent_regions(cells, labels, len(P))
    weighed = normalized_masses(masses, R)
    pairs = [(-abs(weighed[i] - weighed[j]), i, j)
             for i, j in itertools.combinations(range(len(P)), 2)
             if R[i] != R[j] and region_of[i] == region_of[j] >= 0]
    pairs.sort()
    return [Exchange((i, j), (j, i), P[[j, i]].copy(), 0.0) for _, i, j in pairs[:count]]


def _place(cells: MassCells, labels: np.ndarray, P: np.ndarray, weighed: np.ndarray,
           members: dict[tuple[int, int], list[int]], x: tuple[int, ...], a: int, b: int,
           region_of: np.ndarray) -> tuple[tuple[int, ...], tuple[int, ...], np.ndarray]:
    """Who moves where for the class moves ``x`` between targets ``a`` and ``b``."""
    arriving: dict[int, list[int]] = {a: [], b: []}
    for c, v in enumerate(x):
        src, dst, n = (a, b, v) if v > 0 else (b, a, -v)
        arriving[dst] += members[src, c][:n]
    leaving = set(arriving[a]) | set(arriving[b])
    agents: list[int] = []
    into: list[int] = []
    points: list[np.ndarray] = []
    for dst in (a, b):
        if not arriving[dst]:
            continue
        hosts = [int(h) for h in np.argsort(-weighed, kind="stable")
                 if region_of[h] == dst and int(h) not in leaving]
        if not hosts:
            return (), (), np.empty((0, 2))
        placed: dict[int, list[np.ndarray]] = {h: [P[h]] for h in hosts}
        for n, agent in enumerate(arriving[dst]):
            host = hosts[n % len(hosts)]
            own = np.flatnonzero(labels == host)
            if len(own) == 0:
                return (), (), np.empty((0, 2))
            point = _farthest_point(cells, own, np.array(placed[host]))
            placed[host].append(point)
            agents.append(agent)
            into.append(host)
            points.append(point)
    return tuple(agents), tuple(into), np.array(points)
