"""Geometry of planar range scans for sensor-based planning (pure numpy kernels).

A scan is its returns as points ``(M, 2) float64`` [m] relative to the robot (or in the map
frame where stated); directions are unit vectors ``(K, 2)``. :mod:`.bug` plans on these.
"""

from __future__ import annotations

import numpy as np

from coverage_ros.core.geometry import points_in_polygon, polygon_area

#: Neighbouring returns (by bearing) further apart than this many typical beam spacings bound a
#: stretch with no return: open space.
GAP_BEAMS = 2.5

def unit_directions(count: int) -> np.ndarray:
    """``(count, 2)`` unit vectors at angles ``2 pi k / count``."""
    a = 2.0 * np.pi * np.arange(count) / count
    return np.stack([np.cos(a), np.sin(a)], axis=-1)


def free_lengths(offsets: np.ndarray, directions: np.ndarray, radius: float,
                 horizon: float) -> np.ndarray:
    """``(K,)`` [m]: how far a point can move along each unit direction ``(K, 2)`` before it
    comes closer than ``radius`` to one of the obstacle points at ``offsets (M, 2)`` from it
    (capped at ``horizon``). Points it moves away from never block, so a point already too
    close can always back off.

    >>> wall = np.array([[1.0, y] for y in np.linspace(-2, 2, 81)])
    >>> free_lengths(wall, np.array([[1.0, 0.0], [-1.0, 0.0]]), 0.25, 3.0).round(3).tolist()
    [0.75, 3.0]
    """
    dirs = np.asarray(directions, dtype=np.float64).reshape(-1, 2)
    pts = np.asarray(offsets, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return np.full(len(dirs), float(horizon))
    along = dirs @ pts.T  # (K, M)
    across2 = (pts * pts).sum(axis=1)[None, :] - along * along
    r2 = radius * radius
    blocks = (along > 0) & (across2 < r2)
    with np.errstate(invalid="ignore"):
        t = np.where(blocks, along - np.sqrt(np.maximum(r2 - across2, 0.0)), np.inf)
    free: np.ndarray = np.clip(t.min(axis=1), 0.0, horizon)
    return free


def scan_nodes(offsets: np.ndarray, clearance: float,
               jump: float) -> tuple[np.ndarray, np.ndarray]:
    """TangentBug's nodes: endpoints of the continuous obstacle segments of a scan.

    ``offsets (M, 2)`` are returns relative to the robot. Sorted by bearing, two neighbouring
    returns bound a discontinuity when their ranges differ by more than ``jump`` [m] or more
    than ``GAP_BEAMS`` typical beam spacings lie between them (no return: open space, or a
    masked robot). The nearer return of each discontinuity (both, for a gap) is an endpoint
    ``E``; its node is ``E`` moved ``clearance`` sideways toward the open side. Returns
    ``(nodes (N, 2) relative to the robot, open side (N,) +1 counter-clockwise / -1)``.

    >>> wall = np.array([[1.0, y] for y in np.linspace(-0.5, 0.5, 11)])
    >>> nodes, opens = scan_nodes(wall, 0.2, 0.4)
    >>> nodes.round(2).tolist(), opens.tolist()
    ([[0.91, 0.68], [0.91, -0.68]], [1.0, -1.0])
    """
    pts = np.asarray(offsets, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 2:
        return np.zeros((0, 2)), np.zeros(0)
    bearing = np.arctan2(pts[:, 1], pts[:, 0])
    order = np.argsort(bearing)
    pts, bearing = pts[order], bearing[order]
    rng = np.hypot(*pts.T)
    nxt = np.roll(np.arange(len(pts)), -1)
    gap = (np.roll(bearing, -1) - bearing) % (2.0 * np.pi)
    typical = float(np.median(gap))
    hole = gap > GAP_BEAMS * max(typical, 1e-6)
    step = rng[nxt] - rng
    ends: list[int] = []
    opens: list[float] = []
    for k in np.flatnonzero(hole | (np.abs(step) > jump)):
        if hole[k] or step[k] > 0:  # open counter-clockwise of return k
            ends.append(int(k))
            opens.append(1.0)
        if hole[k] or step[k] < 0:  # open clockwise of return k + 1
            ends.append(int(nxt[k]))
            opens.append(-1.0)
    if not ends:
        return np.zeros((0, 2)), np.zeros(0)
    E = pts[ends]
    sgn = np.asarray(opens)
    normal = np.stack([-E[:, 1], E[:, 0]], axis=-1) * (sgn / np.hypot(*E.T))[:, None]
    return E + clearance * normal, sgn


def closest_on_rays(origin: np.ndarray, directions: np.ndarray, lengths: np.ndarray,
                    target: np.ndarray) -> tuple[float, np.ndarray]:
    """The point of the segments ``origin -> origin + lengths[k] * directions[k]`` closest to
    ``target``: ``(distance, point)``."""
    rel = np.asarray(target, dtype=np.float64) - origin
    t = np.clip(directions @ rel, 0.0, lengths)
    pts = origin + t[:, None] * directions
    d = np.hypot(*(pts - target).T)
    k = int(np.argmin(d))
    return float(d[k]), pts[k]


def on_obstacle_side(loop: np.ndarray, side: int, points: np.ndarray) -> np.ndarray:
    """``(N,) bool``: points separated from the free space by a completed boundary loop
    ``(K, 2)`` followed with the obstacle on ``side`` (+1 left): inside the loop when it went
    round the obstacle, outside when it went round the free space (an outer wall).

    >>> square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)  # counter-clockwise
    >>> on_obstacle_side(square, 1, np.array([[0.5, 0.5], [2.0, 0.5]])).tolist()
    [True, False]
    >>> on_obstacle_side(square, -1, np.array([[0.5, 0.5], [2.0, 0.5]])).tolist()
    [False, True]
    """
    inside = points_in_polygon(points, loop)
    obstacle_inside = side * polygon_area(loop) > 0
    return inside if obstacle_inside else ~inside


def closest_on_polyline(polyline: np.ndarray, point: np.ndarray,
                        closed: bool = True) -> np.ndarray:
    """``(2,)``: the point of a polyline ``(K, 2)`` (closed by default) closest to ``point``."""
    a = np.asarray(polyline, dtype=np.float64)
    b = np.roll(a, -1, axis=0) if closed else a[1:]
    a = a if closed else a[:-1]
    ab = b - a
    t = np.clip(((point - a) * ab).sum(axis=1) / np.maximum((ab * ab).sum(axis=1), 1e-300),
                0.0, 1.0)
    q = a + t[:, None] * ab
    closest: np.ndarray = q[int(np.argmin(np.hypot(*(q - point).T)))].copy()
    return closest
