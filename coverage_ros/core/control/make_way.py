"""Making way for a relocating neighbour.

A robot of the closet escape that relocates drives across the map to another cell's point; it
publishes that it does and where to (``relocating``, ``to_x``, ``to_y``:
:mod:`coverage_ros.core.strategies.handover.published`). Its planner knows the map alone, and a
settled robot whose goal lies in a doorway on its way holds it there: the safety filter keeps
the two apart and no detour fits through the door beside it.

So a robot that does not relocate itself, whose position or goal lies on such a neighbour's way
(within :data:`AHEAD` of the neighbour along the path it would plan, nearer to that path than
the distance the safety filter keeps plus :data:`MARGIN`), heads instead for the nearest free
point off every such neighbour's whole path that it reaches in a straight line (mode
``make_way``; a point further along the path would only put off the meeting), and back to its
own goal once the neighbour has passed, arrived or given up. Where no such point lies within
:data:`STEP_ASIDE` (a corridor too narrow for two robots side by side), the decision stands.

A neighbour's path is planned once per relocation (:class:`Ways`: a path across a large map
takes seconds) and followed from the point of it nearest the neighbour while the neighbour
keeps within :data:`STRAY` of it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from coverage_ros.core.control.planning import PATH_MARGIN, plan_path, segment_free
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geometry import distance_to_segments
from coverage_ros.core.strategies import Decision
from coverage_ros.core.strategies.base import Neighbour
from coverage_ros.core.strategies.handover.published import destination, value

#: [m] relocating neighbours within this distance of the robot are looked at
NEAR = 3.0
#: [m] of a relocating neighbour's way looked at, from where it stands
AHEAD = 2.5
#: [m] kept from a neighbour's way beyond the distance the safety filter keeps
MARGIN = 0.1
#: [m] the farthest a robot goes to make way
STEP_ASIDE = 1.5
#: candidate points (nearest first) checked for a straight way there
TRIES = 24
#: [m] a neighbour farther than this from the path planned for it gets a new one
STRAY = 0.5


class Ways:
    """The paths of relocating neighbours, by robot id, each with the point it leads to."""

    def __init__(self) -> None:
        self._paths: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def of(self, domain: CoverageDomain, n: Neighbour, to: np.ndarray) -> np.ndarray | None:
        """``(M, 2)`` [m] ``n``'s way from where it stands to ``to`` (None: unreachable)."""
        known = self._paths.get(n.robot_id)
        if known is not None and np.array_equal(known[0], to):
            rest = remaining(known[1], n.position)
            if rest is not None:
                return rest
        path = plan_path(domain, n.position, to)
        if path is None:
            self._paths.pop(n.robot_id, None)
        else:
            self._paths[n.robot_id] = (np.array(to, dtype=np.float64), path)
        return path

    def keep_only(self, robot_ids: set[int]) -> None:
        """Forget the paths of every other robot (they no longer relocate near here)."""
        for rid in set(self._paths) - robot_ids:
            del self._paths[rid]


def make_way(domain: CoverageDomain, decision: Decision, pose: np.ndarray,
             neighbours: Sequence[Neighbour], keep_from: Callable[[Neighbour], float],
             known: Ways | None = None) -> Decision:
    """``decision``, or one heading off the way of a relocating neighbour (module docstring).
    ``keep_from(n)`` [m]: the centre distance the safety filter keeps from neighbour ``n``;
    ``known``: the neighbours' paths planned so far (kept up to date here)."""
    known = Ways() if known is None else known
    here = np.asarray(pose[:2], dtype=np.float64)
    near = [n for n in neighbours if value(n, "relocating") > 0
            and float(np.hypot(*(n.position - here))) <= NEAR]
    known.keep_only({n.robot_id for n in near})
    if decision.velocity is not None or decision.goal is None or decision.mode == "relocate":
        return decision
    ways = []
    for n in near:
        to = destination(n)
        path = None if to is n.position else known.of(domain, n, to)
        if path is None:
            continue
        way = ahead(path, AHEAD)
        need = keep_from(n) + MARGIN
        if min(distance_to_path(way, np.stack([here, decision.goal]))) < need:
            ways.append((path, need, n.position))
    if not ways:
        return decision
    spot = aside(domain, here, ways)
    if spot is None:
        return decision
    return replace(decision, goal=spot, target=spot, mode="make_way", converged=False)


def ahead(path: np.ndarray, length: float) -> np.ndarray:
    """The first ``length`` [m] of ``path (M, 2)`` (its last point cut to that length)."""
    legs = np.hypot(*np.diff(path, axis=0).T)
    walked = np.concatenate([[0.0], np.cumsum(legs)])
    k = int(np.searchsorted(walked, length))
    if k >= len(path):
        return path
    t = (length - walked[k - 1]) / max(legs[k - 1], 1e-12)
    return np.vstack([path[:k], path[k - 1] + t * (path[k] - path[k - 1])])


def remaining(path: np.ndarray, position: np.ndarray) -> np.ndarray | None:
    """``path (M, 2)`` from the point of it nearest ``position`` on, with ``position`` first;
    None when ``position`` is farther than :data:`STRAY` from it."""
    if len(path) < 2:
        return None
    a, b = path[:-1], path[1:]
    ab = b - a
    t = np.clip(((position - a) * ab).sum(axis=1) / np.maximum((ab * ab).sum(axis=1), 1e-12),
                0.0, 1.0)
    foot = a + t[:, None] * ab
    gap = np.hypot(*(foot - position).T)
    k = int(np.argmin(gap))
    if gap[k] > STRAY:
        return None
    return np.vstack([position, foot[k], path[k + 1:]])


def distance_to_path(path: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``(N,)`` [m] from each of ``points (N, 2)`` to the polyline ``path (M >= 2, 2)``."""
    return distance_to_segments(points, path[:-1], path[1:])


def aside(domain: CoverageDomain, here: np.ndarray,
          ways: Sequence[tuple[np.ndarray, float, np.ndarray]]) -> np.ndarray | None:
    """(2,) [m] the nearest free point within :data:`STEP_ASIDE` of ``here`` that keeps the
    distance ``need`` from every ``(path, need, neighbour position)`` and is reached in a
    straight line that passes no such neighbour nearer than the safety filter keeps (or than
    the robot is now); None if none."""
    free = domain.margin_free(PATH_MARGIN)
    g = domain.to_grid(here[None])[0]
    reach = STEP_ASIDE / domain.resolution
    H, W = domain.shape
    c0, c1 = max(int(g[0] - reach), 0), min(int(g[0] + reach) + 1, W)
    r0, r1 = max(int(g[1] - reach), 0), min(int(g[1] + reach) + 1, H)
    rows, cols = np.nonzero(free[r0:r1, c0:c1])
    if len(rows) == 0:
        return None
    points = domain.to_map(np.stack([cols + c0 + 0.5, rows + r0 + 0.5], axis=1))
    off = np.hypot(*(points - here).T)
    keep = off <= STEP_ASIDE
    for way, need, _ in ways:
        keep &= distance_to_path(way, points) >= need
    points, off = points[keep], off[keep]
    # (the way there may not pass a neighbour nearer than the safety filter keeps, or than
    # the robot is now when it is nearer already)
    limits = [min(need - MARGIN, float(np.hypot(*(p - here)))) - 1e-9 for _, need, p in ways]
    for k in np.argsort(off, kind="stable")[:TRIES]:
        q = points[k]
        line = np.stack([here, q])
        if all(distance_to_path(line, p[None])[0] >= limit
               for (_, _, p), limit in zip(ways, limits, strict=True)) \
                and segment_free(domain, here, q):
            return np.asarray(q)
    return None
