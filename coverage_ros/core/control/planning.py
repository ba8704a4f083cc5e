"""Paths for a differential-drive robot toward its coverage goal.

:func:`plan_path` finds a path on the configuration-space graph (free cells inflated by the
robot radius) from the robot to its goal - the shortest within a window around both when there
is one there within the detour limit (without a limit, within the default one), else the
shortest over the whole map - shortened by line of sight into a few waypoints (the straight
segment when it is free, which is the usual case: strategies clip their goals to what the
robot can see). :func:`segment_free` is the collision check both use.

Paths are ``(M, 2)`` map-frame points [m].
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
from scipy.sparse.csgraph import connected_components, dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.local_search import (
    BLOCK,
    LocalGraph,
    build_local_graph,
    local_graph_for,
)

#: Fraction of a cell between collision checks along a segment or arc.
CHECK_STEP_CELLS = 0.25
#: [m] extra clearance beyond the robot radius that planned shortcuts keep from walls (pure
#: pursuit cuts corners a little; this keeps the robot off them).
PATH_MARGIN = 0.05
#: [m] the first path search looks this far around the box of start and goal.
PLAN_WINDOW_MARGIN = 2.0
#: A goal farther by path than this many times its straight-line distance (+ 2 m) is not
#: planned for by default: a step of the robot's own cell is near by path too, and the search
#: for a goal out of reach stops there instead of crossing the whole map.
MAX_DETOUR = 4.0


def segment_free(domain: CoverageDomain, a: np.ndarray, b: np.ndarray,
                 margin: float = 0.0) -> bool:
    """Whether every point of the segment a-b (map frame) lies on a free C-space cell, and
    (``margin`` > 0) at least ``margin`` farther from obstacles than the C-space requires."""
    ga, gb = domain.to_grid(np.stack([a, b]))
    n = max(2, int(math.ceil(float(np.hypot(*(gb - ga))) / CHECK_STEP_CELLS)) + 1)
    t = np.linspace(0.0, 1.0, n)[:, None]
    pts = ga + t * (gb - ga)
    if not points_free(domain, pts):
        return False
    if margin <= 0:
        return True
    cells = np.floor(pts[:, ::-1]).astype(np.int64)
    need = domain.robot_radius + 0.5 * domain.resolution + margin
    return bool((domain.clearance[cells[:, 0], cells[:, 1]] >= need).all())


def points_free(domain: CoverageDomain, grid_pts: np.ndarray) -> bool:
    H, W = domain.shape
    c = np.floor(grid_pts[:, 0]).astype(np.int64)
    r = np.floor(grid_pts[:, 1]).astype(np.int64)
    inside = (r >= 0) & (r < H) & (c >= 0) & (c < W)
    return bool(inside.all() and domain.free[r, c].all())


def plan_path(domain: CoverageDomain, start: np.ndarray, goal: np.ndarray,
              max_detour: float = MAX_DETOUR) -> np.ndarray | None:
    """``(M, 2)`` waypoints from ``start`` to ``goal`` (both included), or None when the goal
    cannot be reached within ``max_detour`` times the straight-line distance (+ 2 m); with
    ``max_detour`` infinite, None only when no path reaches it at all."""
    start = np.asarray(start, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    straight = float(np.hypot(*(goal - start)))
    if segment_free(domain, start, goal, PATH_MARGIN) or (
            straight < 4 * domain.resolution and segment_free(domain, start, goal)):
        return np.stack([start, goal])
    limit = math.inf if math.isinf(max_detour) else max_detour * straight + 2.0
    # First a window around start and goal (paths to a coverage goal are short), then the
    # whole map. Without a limit the window's path counts only within the default detour:
    # a longer one may wind through the window while the map has a far shorter way round.
    near = limit if math.isfinite(limit) else MAX_DETOUR * straight + 2.0
    for window, most in ((PLAN_WINDOW_MARGIN, near), (None, limit)):
        if window is None and math.isinf(limit) and not _connected(domain, start, goal):
            return None  # (else every update would search all the robot's side of the map)
        local = _planning_graph(domain, start, goal, window)
        nodes, costs, _ = domain.snap(start)
        csr = local.with_sources([(local.local_of(nodes), costs)])
        dist, pred = dijkstra(csr, directed=True, indices=local.n + 1, limit=most,
                              return_predecessors=True)
        lids = local.local_of(domain.snap(goal)[0])
        lids = lids[lids > 0]
        if len(lids) and np.isfinite(dist[lids]).any():
            break
    else:
        return None
    v = int(lids[np.argmin(dist[lids])])
    chain = []
    while 0 < v <= local.n:
        chain.append(int(local.global_nodes[v - 1]))
        v = int(pred[v])
    cells = domain.to_map(domain.node_centers(np.array(chain[::-1], dtype=np.int64)))
    return shortcut(domain, np.vstack([start, cells, goal]))


def _connected(domain: CoverageDomain, start: np.ndarray, goal: np.ndarray) -> bool:
    """Whether a free node ``start`` snaps to shares a connected part of the domain's graph
    with one ``goal`` snaps to (the parts memoized per domain)."""
    key = "plan_components"
    parts: tuple[LocalGraph, np.ndarray] | None = domain._cache.get(key)
    if parts is None:
        whole = local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1), math.inf)
        _, label = connected_components(whole.with_sources([]), directed=True,
                                        connection="weak")
        parts = domain._cache[key] = (whole, label)
    whole, label = parts
    a, b = (whole.local_of(domain.snap(p)[0]) for p in (start, goal))
    return bool(np.isin(label[a[a > 0]], label[b[b > 0]]).any())


def _planning_graph(domain: CoverageDomain, start: np.ndarray, goal: np.ndarray,
                    margin: float | None) -> LocalGraph:
    """The search graph of the box around start and goal grown by ``margin`` [m] (None: the
    whole domain)."""
    if margin is None or any(domain.graph.wrap):
        return local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1), math.inf)
    g = domain.to_grid(np.stack([start, goal]))
    m = margin / domain.resolution
    H, W = domain.shape
    Hb, Wb = -(-H // BLOCK), -(-W // BLOCK)
    blocks = np.zeros((Hb, Wb), dtype=bool)
    r0, r1 = (int(np.clip((g[:, 1].min() - m) // BLOCK, 0, Hb)),
              int(np.clip((g[:, 1].max() + m) // BLOCK + 1, 0, Hb)))
    c0, c1 = (int(np.clip((g[:, 0].min() - m) // BLOCK, 0, Wb)),
              int(np.clip((g[:, 0].max() + m) // BLOCK + 1, 0, Wb)))
    blocks[r0:r1, c0:c1] = True
    return build_local_graph(domain, blocks)


def shortcut(domain: CoverageDomain, path: np.ndarray) -> np.ndarray:
    """Greedy line-of-sight shortening: from each waypoint, jump to the farthest one reachable
    in a straight line that keeps :data:`PATH_MARGIN` from the walls (else the next one).

    Candidates are checked farthest first, a batch at a time in one vectorized pass each
    (paths of exploring robots cross whole maps: hundreds of waypoints), up to
    ``SHORTCUT_REACH`` waypoints ahead; a waypoint from which not even the one after next is
    in clear sight (a path hugging an obstacle) keeps the next one without a search."""
    ok = domain.margin_free(PATH_MARGIN)
    g = domain.to_grid(path)
    out = [path[0]]
    i = 0
    while i < len(path) - 1:
        i = _farthest_visible(ok, g, i)
        out.append(path[i])
    return np.array(out)


#: Waypoints ahead that shortcut() considers from each waypoint (6.4 m of a grid path at 5 cm).
SHORTCUT_REACH = 128
#: Candidates checked per vectorized pass of :func:`shortcut`.
SHORTCUT_BATCH = 64


def _farthest_visible(ok: np.ndarray, g: np.ndarray, i: int) -> int:
    """The largest j in (i + 1, i + SHORTCUT_REACH] whose segment from waypoint i is clear in
    ``ok`` (sampled like :func:`segment_free`), else i + 1 (also when i + 2 is not clear)."""
    hi = min(len(g) - 1, i + SHORTCUT_REACH)
    if hi > i + 1 and _visible(ok, g[i], g[i + 2:i + 3])[0] == 0:
        return i + 1
    while hi > i + 1:
        lo = max(i + 2, hi - SHORTCUT_BATCH + 1)
        js = np.arange(hi, lo - 1, -1)
        clear = _visible(ok, g[i], g[js])
        if clear.any():
            return int(js[int(np.argmax(clear))])
        hi = lo - 1
    return i + 1


def _visible(ok: np.ndarray, a: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """``(m,) bool``: whether each segment from grid point ``a`` to ``ends (m, 2)``, sampled
    like :func:`segment_free`, stays on cells of ``ok``."""
    H, W = ok.shape
    d = ends - a
    counts = np.maximum(2, np.ceil(np.hypot(d[:, 0], d[:, 1]) / CHECK_STEP_CELLS)
                        .astype(np.int64) + 1)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    seg = np.repeat(np.arange(len(d)), counts)
    t = (np.arange(int(counts.sum())) - starts[seg]) / (counts[seg] - 1)
    pts = a + t[:, None] * d[seg]
    c = np.floor(pts[:, 0]).astype(np.int64)
    r = np.floor(pts[:, 1]).astype(np.int64)
    inside = (r >= 0) & (r < H) & (c >= 0) & (c < W)
    free = np.zeros(len(pts), dtype=bool)
    free[inside] = ok[r[inside], c[inside]]
    return np.logical_and.reduceat(free, starts)


#: [m] a detour keeps this much more than the safety filter needs from the robot it passes
#: (half of it when no bend with all of it is free: a narrow corridor).
DETOUR_MARGIN = 0.06
#: [rad] step between the points of the arc a detour bends around a robot in the way: chords
#: of 30 degrees stay within 4 % of the arc's radius.
DETOUR_STEP = math.radians(30.0)
#: [rad] where the arc ends: this far past the side of the robot in the way, ahead of it.
DETOUR_END = math.radians(60.0)
#: [m] of path from the robot within which a detour looks for the robot in the way (the
#: safety filter holds a robot for neighbours closer than this).
DETOUR_REACH = 1.0


def detour(domain: CoverageDomain, path: np.ndarray | None, positions: np.ndarray,
           clearances: np.ndarray) -> np.ndarray | None:
    """``path`` bent around the first robot in its way: neighbours at ``positions (n, 2)``
    [m], from which the safety filter keeps ``clearances (n,)`` [m]. Around the first one
    that a leg within :data:`DETOUR_REACH` of the start runs into, the path goes on an arc at
    its clearance plus :data:`DETOUR_MARGIN` from the robot's own bearing from it (so the first
    leg moves round the neighbour, not past it), round the side it is already on
    (on a tie, the right: the side a robot gives way to, :mod:`.recovery`), else round the
    other, and takes up again at its first waypoint past the arc. When no bend from the robot
    is free (a path round a corner), the bend starts at that leg. ``path`` as it was when no
    neighbour is in the way or no bend is free.

    The planner knows only the map: a robot standing on the straight line to another one's
    goal (a settled robot on a relocating one's way) held it until it moved (the live Lee &
    Lee Fig. 18a-c: 45 s, giving way three times and planning the same straight line again).
    Not only the first leg: a path starts at the robot and goes on from the nearest cell
    centre, so its first leg may be a few centimetres long, in any direction, and the robot in
    the way on the next."""
    if path is None or len(path) < 2 or len(positions) == 0:
        return path
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    need = np.asarray(clearances, dtype=np.float64).reshape(-1)
    walked = 0.0  # [m] of path before leg k
    for k in range(len(path) - 1):
        if walked > DETOUR_REACH:
            break
        a, b = path[k], path[k + 1]
        length = float(np.hypot(*(b - a)))
        if length < domain.resolution:  # a snap to a cell centre: no direction to speak of
            walked += length
            continue
        u = (b - a) / length
        left = np.array([-u[1], u[0]])
        along, across = (positions - a) @ u, (positions - a) @ left
        blocking = (along > -need) & (along < length + need) & (np.abs(across) < need) \
            & (walked + along <= DETOUR_REACH)
        walked += length
        if not blocking.any():
            continue
        j = int(np.argmin(np.where(blocking, along, np.inf)))
        for radius in float(need[j]) + np.array([DETOUR_MARGIN, 0.5 * DETOUR_MARGIN]):
            for s in dict.fromkeys((0, k)):  # from the robot, else from the leg's start
                bent = _around(domain, path, s, k, u, positions[j], float(need[j]), radius)
                if bent is not None:
                    return bent
        return path
    return path


def _around(domain: CoverageDomain, path: np.ndarray, s: int, k: int, u: np.ndarray,
            centre: np.ndarray, need: float, radius: float) -> np.ndarray | None:
    """:func:`detour`'s bend from waypoint ``s`` around ``centre`` (the filter keeping
    ``need`` [m] from it) at ``radius``, in the way of leg ``k`` (direction ``u``); None if no
    side is free."""
    a, rest = path[s], path[k + 1:]
    left = np.array([-u[1], u[0]])
    offset = a - centre
    # [m] no new leg comes nearer the neighbour than the filter's clearance, or than the
    # robot already is (it may stand nearer: it then moves no nearer)
    floor = min(need, float(np.hypot(*offset))) - 1e-3
    start = math.atan2(offset[1], offset[0])
    arcs = []
    for side in (-1.0, 1.0):  # right of the way, left of it
        end_dir = side * math.cos(DETOUR_END) * left + math.sin(DETOUR_END) * u
        end = math.atan2(end_dir[1], end_dir[0])
        sense = -side  # round the right: counter-clockwise
        sweep = (sense * (end - start)) % (2 * math.pi)
        if sweep > 2 * math.pi - DETOUR_END - DETOUR_STEP:
            continue  # already past its end on this side (ahead of the neighbour)
        steps = np.arange(DETOUR_STEP, sweep - DETOUR_STEP / 3, DETOUR_STEP)
        angles = start + sense * np.append(steps, sweep)
        arcs.append((sweep + 1e-6 * side, centre + radius * np.column_stack(
            [np.cos(angles), np.sin(angles)])))
    for _, arc in sorted(arcs, key=lambda sa: sa[0]):
        # Back on the path at its first waypoint past the arc, outside the circle (the goal
        # at the latest).
        past = ((rest - a) @ u >= float((arc[-1] - a) @ u)) \
            & (np.hypot(*(rest - centre).T) >= radius)
        keep = int(np.argmax(past)) if past.any() else len(rest) - 1
        new = np.vstack([a, arc, rest[keep]])
        if _distance(centre, new[:-1], new[1:]).min() >= floor and \
                all(segment_free(domain, p, q) for p, q in pairwise(new)):
            return np.vstack([path[:s + 1], arc, rest[keep:]])
    return None


def _distance(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(m,)`` [m] from point ``c`` to each segment ``a[i]``-``b[i]`` (``(m, 2)`` each)."""
    d = b - a
    t = np.clip(np.einsum("ij,ij->i", c - a, d) / np.maximum(np.einsum("ij,ij->i", d, d),
                                                              1e-18), 0.0, 1.0)
    dist: np.ndarray = np.hypot(*(a + t[:, None] * d - c).T)
    return dist
