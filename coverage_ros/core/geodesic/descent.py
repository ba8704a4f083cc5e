"""From the generalized Lloyd control to a goal the robot can reach (Bhattacharya et al. 2014,
Sec. 4).

The control of Eq. 8 is a step toward the cell's virtual centroid. :func:`reachable_goal` keeps
the part of that straight step that stays in free space; when the step is blocked almost at once
(a robot in a doorway heading for a centroid beyond the door frame) it walks along the gradient
through the free space instead (:func:`descent_walk`, the paper's next-vertex rule repeated),
or - where every step along the gradient is blocked, as at the corner of a door jamb whose way
on starts sideways or backwards - heads for the vertex within a short path that lies farthest
along the gradient (:func:`ball_descent`). :func:`next_vertex` is the paper's rule itself
(pseudo-code line 32).

Grid coordinates ``(gx, gy)`` are in cells; covectors in grid axes (chart units).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain

#: A straight step to the virtual centroid that is blocked before this fraction of its length
#: is replaced by a walk along the gradient through the free space, of at most WALK_CELLS.
BLOCKED_FRACTION = 0.25
WALK_CELLS = 20.0
#: [cells] A step clipped this close to BLOCKED_FRACTION of its length counts as not blocked:
#: the clip's samples split the step into equal parts, so it stops at exactly a quarter of it
#: whenever the number of parts is a multiple of 4, and the comparison would turn on the last
#: bits of the control (two exact computations of it then chose different goals).
BLOCKED_SLACK_CELLS = 1e-9
#: Walk steps must make progress along the gradient: cos of at most ~84 degrees off it (a robot
#: beside a door jamb may have to step almost sideways before it can go on).
WALK_MIN_ALIGNMENT = 0.1
#: The farthest-along vertex of :func:`ball_descent` is searched within paths this many times
#: the walk's length (a detour round a jamb is longer than the straight way on).
BALL_PATH_FACTOR = 1.5


def reachable_goal(domain: CoverageDomain, base_node: int, own_grid: np.ndarray,
                   step_grid: np.ndarray, covector: np.ndarray) -> np.ndarray:
    """Grid point the robot at ``own_grid`` (on vertex ``base_node``) should head for, given
    the control step ``step_grid`` [cells] and the covector I_k."""
    goal_grid = clip_reachable(domain, own_grid, own_grid + step_grid)
    wanted = float(np.hypot(*step_grid))
    reached = float(np.hypot(*(goal_grid - own_grid)))
    if wanted > 1.0 and reached < BLOCKED_FRACTION * wanted - BLOCKED_SLACK_CELLS:
        length = min(wanted, WALK_CELLS)
        walk = descent_walk(domain, base_node, covector, length)
        if float(np.hypot(*(walk - own_grid))) > float(np.hypot(*(goal_grid - own_grid))):
            goal_grid = walk
        # The walk stops where no step makes progress along the gradient (the corner of a
        # door jamb: the robot must step sideways or back first). A robot left there would
        # count as converged for ever while its cell's centroid lies beyond the door.
        direction = step_grid / wanted
        ball = ball_descent(domain, base_node, direction, length)
        if float((ball - goal_grid) @ direction) > 1.0:
            goal_grid = ball
    return goal_grid


def clip_reachable(domain: CoverageDomain, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """The farthest point toward ``goal`` on the straight segment that stays in free cells."""
    if any(domain.graph.wrap):
        return goal
    d = goal - start
    length = float(np.hypot(*d))
    if length < 1e-9:
        return goal
    t = np.linspace(0.0, 1.0, int(math.ceil(length * 4.0)) + 2)
    pts = start + t[:, None] * d
    _, _, ok = domain.free_at_grid(pts)
    if ok.all():
        return goal
    if not ok[0]:
        return start
    last = int(np.argmin(ok)) - 1
    reached: np.ndarray = pts[max(last, 0)]
    return reached


def descent_walk(domain: CoverageDomain, base: int, covector: np.ndarray,
                  length_cells: float) -> np.ndarray:
    """Grid point reached by walking from vertex ``base`` along graph edges, each step to the
    neighbour best aligned with the covector (Bhattacharya et al.'s next-vertex rule, repeated),
    for about ``length_cells``; stops where no neighbour makes progress along it."""
    graph = domain.graph
    W = graph.shape[1]
    direction = covector / max(float(np.hypot(*covector)), 1e-300)
    dirs = graph.offsets[:, ::-1].astype(np.float64)  # (x, y) per offset, cells
    lengths = np.hypot(dirs[:, 0], dirs[:, 1])
    align = (dirs @ direction) / lengths
    node, travelled, seen = base, 0.0, {base}
    while travelled < length_cells:
        r, c = divmod(node, W)
        ok = np.isfinite(graph.cost[r, c]) & (align > WALK_MIN_ALIGNMENT)
        if not ok.any():
            break
        k = int(np.argmax(np.where(ok, align, -np.inf)))
        nxt = int(graph.neighbour_index(k)[r, c])
        if nxt in seen:
            break
        seen.add(nxt)
        node = nxt
        travelled += float(lengths[k])
    end: np.ndarray = domain.node_centers(np.array([node]))[0]
    return end


def ball_descent(domain: CoverageDomain, base: int, direction: np.ndarray,
                 length_cells: float) -> np.ndarray:
    """Grid point of the vertex farthest along ``direction`` (a unit vector, grid axes) among
    those within a path of ``BALL_PATH_FACTOR * length_cells`` cells from vertex ``base`` (path
    lengths in the domain's metric, scaled by the cheapest edge at ``base``); ``base`` itself
    if it has no edges."""
    graph = domain.graph
    W = graph.shape[1]
    r, c = divmod(base, W)
    lengths = np.hypot(graph.offsets[:, 0], graph.offsets[:, 1]).astype(np.float64)
    cost = graph.cost[r, c]
    ok = np.isfinite(cost)
    if not ok.any():
        at_base: np.ndarray = domain.node_centers(np.array([base]))[0]
        return at_base
    unit = float(np.min(cost[ok] / lengths[ok]))
    dist = dijkstra(graph.csr, directed=True, indices=base,
                    limit=BALL_PATH_FACTOR * length_cells * unit)
    reached = np.flatnonzero(np.isfinite(dist))
    pts = domain.node_centers(reached)
    own = domain.node_centers(np.array([base]))[0]
    progress = (pts - own) @ direction
    best = np.flatnonzero(progress >= progress.max() - 1e-9)
    k = best[np.argmin(dist[reached[best]])]  # the nearest of equally good ones
    farthest: np.ndarray = pts[k]
    return farthest


def next_vertex(domain: CoverageDomain, base: int, covector: np.ndarray) -> np.ndarray:
    """The graph neighbour of vertex ``base`` best aligned with the covector (paper, l. 32)."""
    graph = domain.graph
    W = graph.shape[1]
    r, c = divmod(base, W)
    ok = np.isfinite(graph.cost[r, c])
    best = base
    if ok.any():
        v = graph.offsets[ok][:, ::-1].astype(np.float64) * domain.resolution  # (x, y) chart
        score = v @ covector
        k = int(np.argmax(score))
        if score[k] > 0:
            best = int(graph.neighbour_index(int(np.flatnonzero(ok)[k]))[r, c])
    vertex: np.ndarray = domain.to_map(domain.node_centers(np.array([best])))[0]
    return vertex
