"""What a robot offers its neighbours in the closet escape: a split of its own cell with a
second generator of its power weight (:mod:`.protocol`), and what that split saves - the
second term of a handover's bound (:mod:`.bounds`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.whole_map import nearest
from coverage_ros.core.strategies.handover.bounds import SLACK_EDGES, node_points


@dataclass(frozen=True)
class SplitOffer:
    """What splitting the own cell with a second generator would save."""

    gain: float  # H_k - cost of the split (>= 0), units of H
    point: np.ndarray  # (2,) [m] map frame: where the second generator goes (a node of the cell)
    base: float  # H_k, the own cell's cost before the split


#: Further starts of :func:`split_offers`' second offer, each the node farthest from the own
#: generator and every earlier start: a cell reaching into two rooms splits best in either.
SECOND_STARTS = 2


def split_offer(domain: CoverageDomain, nodes: np.ndarray, g_own: np.ndarray, cost: float,
                weight: float, cell_radius: float, steps: int,
                method: str = "auto") -> SplitOffer | None:
    """The best split of the own cell ``nodes`` (distances ``g_own`` from the own generator,
    cost ``cost``) with a second generator of the own power weight: started at the node
    farthest from the own generator, moved ``steps`` times to the mass centroid of its part
    (the part's node nearest to it); the least cost seen. None for a cell of fewer than two
    nodes."""
    offers = split_offers(domain, nodes, g_own, cost, weight, cell_radius, steps, method,
                          second=False)
    return offers[0] if offers else None


def split_offers(domain: CoverageDomain, nodes: np.ndarray, g_own: np.ndarray, cost: float,
                 weight: float, cell_radius: float, steps: int, method: str = "auto",
                 second: bool = True) -> list[SplitOffer]:
    """:func:`split_offer`'s split, then (``second``) the best split from
    :data:`SECOND_STARTS` further starts whose point lies outside the first split's part (the
    nodes its second generator would take) if it saves more than the first: the cell's other
    room, where it spans two and the farthest node lies in the smaller. Empty for a cell of
    fewer than two nodes."""
    splits = split_parts(domain, nodes, g_own, weight, cell_radius, steps, method,
                         1 + SECOND_STARTS if second else 1)
    if not splits:
        return []
    first = splits[0]
    offers = [SplitOffer(gain=max(cost - first.cost, 0.0), point=first.point.copy(), base=cost)]
    other: Split | None = None
    for split in splits[1:]:
        if not first.part[split.at] and split.cost < min(first.cost, cost) \
                and (other is None or split.cost < other.cost):
            other = split
    if other is not None:
        offers.append(SplitOffer(gain=cost - other.cost, point=other.point.copy(), base=cost))
    return offers


def room_offers(domain: CoverageDomain, nodes: np.ndarray, g_own: np.ndarray, cost: float,
                weight: float, cell_radius: float, steps: int, starts: int,
                taken: np.ndarray, method: str = "auto") -> list[SplitOffer]:
    """Splits of a cell ``nodes`` from ``starts`` farthest-point starts (:func:`split_parts`)
    that save something, one per part: a split whose part holds the point of an earlier one,
    or one of ``taken (k, 2)`` [m] (offers already made), is the same room's. The cell of a
    robot that covers several rooms from a corridor offers one point per room, largest saving
    first - not only the one or two its own splits rank best, which need not be where a robot
    moving in pays once the team re-spreads."""
    pts = node_points(domain, np.asarray(nodes, dtype=np.int64))
    taken_at = [int(np.argmin(np.hypot(*(pts - t).T))) for t in np.reshape(taken, (-1, 2))]
    kept: list[Split] = []
    for split in split_parts(domain, nodes, g_own, weight, cell_radius, steps, method, starts):
        if split.cost < cost and not any(split.part[k.at] or k.part[split.at] for k in kept) \
                and not any(split.part[t] for t in taken_at):
            kept.append(split)
    kept.sort(key=lambda k: k.cost)
    return [SplitOffer(gain=cost - k.cost, point=k.point.copy(), base=cost) for k in kept]


@dataclass(frozen=True)
class Split:
    """One split of a cell with a second generator."""

    cost: float  # of the cell split so, units of H
    point: np.ndarray  # (2,) [m] the second generator (a node of the cell)
    at: int  # index of that node in the cell's nodes
    part: np.ndarray  # (len(nodes),) bool: the nodes the second generator takes


def split_parts(domain: CoverageDomain, nodes: np.ndarray, g_own: np.ndarray, weight: float,
                cell_radius: float, steps: int, method: str, starts: int,
                limit: float | None = None) -> list[Split]:
    """The least-cost split of the cell ``nodes`` (distances ``g_own`` from the own
    generator) from each of ``starts`` starts: the node farthest from the own generator, then
    each the node farthest from it and every earlier start (fewer where none is left in
    reach); from a start, the second generator moves ``steps`` times to the mass centroid of
    its part (the part's node nearest to it), and the least cost seen counts. Empty for a cell
    of fewer than two nodes.

    The second generator's searches reach ``limit`` (chart units; None: the cell's farthest
    node from the own generator, or twice ``cell_radius`` if that is nearer). A node farther
    from the second generator than that is farther from it than from the own one, so it stays
    the own whether it is reached or not: every limit from the farthest node on gives the same
    splits, the nearest one at the least cost (in the open, a quarter of the nodes that twice
    the radius reaches)."""
    nodes = np.asarray(nodes, dtype=np.int64)
    if len(nodes) < 2:
        return []
    wdA = domain.mass_element.ravel()[nodes]
    pts = node_points(domain, nodes)
    own = g_own * g_own - weight ** 2
    if limit is None:
        limit = min(2.0 * cell_radius + SLACK_EDGES * domain.graph.max_edge_cost,
                    float(np.max(g_own)))
    apart = np.array(g_own, dtype=np.float64)  # [m] from the own generator and the starts

    def descend(start: int) -> Split:
        """The least split cost from node ``start``, its point and its part."""
        nonlocal apart
        s = pts[start]
        best = Split(math.inf, s, start, np.zeros(len(nodes), bool))
        for step in range(max(1, steps)):
            gs = nearest(domain, s[None], limit, method)[0][nodes]
            if step == 0:
                apart = np.minimum(apart, gs)  # (inf beyond the search's reach)
            theirs = np.where(np.isfinite(gs), gs * gs - weight ** 2, np.inf)
            mine = theirs < own
            split = float(np.where(mine, theirs, own).dot(wdA))
            if split < best.cost:
                best = Split(split, s, int(np.argmin(np.hypot(*(pts - s).T))), mine)
            m = float(wdA[mine].sum())
            if m <= 0:
                break
            centroid = (pts[mine] * wdA[mine, None]).sum(axis=0) / m
            part = pts[mine]
            nxt = part[int(np.argmin(np.hypot(*(part - centroid).T)))]
            if np.allclose(nxt, s):
                break
            s = nxt
        return best

    out = [descend(int(np.argmax(g_own)))]
    for _ in range(starts - 1):
        far = int(np.argmax(apart))
        if not (apart[far] > 0.0 and np.isfinite(apart[far])):
            break
        out.append(descend(far))
    return out
