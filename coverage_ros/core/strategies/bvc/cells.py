"""Buffered Voronoi cells from raw range points (Wang et al. 2024, Sec. IV-A/B).

A robot at ``p`` with radius ``r`` builds its safe convex cell from what it senses and from
its neighbours' positions only:

1. **Visible obstacle points** (Eq. 5): every obstacle point ``q`` within the sensing radius
   ``R`` is mirrored along its ray, ``q' = d + 2 (R - |d|) d / |d|`` with ``d = q - p``, so near
   points land far out. The vertices of the convex hull of the mirrored points (and of the
   origin, as in Katz et al.'s hidden point removal) are the points that bound the free space
   around the robot; points hidden behind them are dropped.
2. **Robot-obstacle hyperplanes** (Eq. 6): ``min a'a  s.t.  (q - p)' a >= 1``, one small QP per
   visible point. With one constraint its unique solution is ``a = d / |d|^2`` (Cauchy-Schwarz:
   any feasible ``a`` has ``|a| >= 1 / |d|``, with equality only along ``d``), shifted to be tight
   at the point: ``b = a' q``. :func:`eq6_hyperplane` is that closed form;
   the tests compare it with scipy's SLSQP on the same QP.
3. **Robot-robot hyperplanes** (Eq. 4): the perpendicular bisector of ``p`` and each neighbour.
   We write ``a_ij = p_j - p_i`` (pointing away from the own robot, as the obstacle normals do) so
   that both kinds read ``a' x <= b``; the paper's ``p_i - p_j`` with ``<=`` would keep the wrong
   side.
4. **Buffers** ``beta = r |a|`` and the cell of Eq. 7, ``a' x <= b - beta`` for every
   hyperplane, intersected with the sensing disc (shrunk by ``r``, so that an obstacle just
   beyond the sensor's reach is still ``r`` away) and the map's bounding box. The result is a
   convex polygon.

Lemma 1 of the paper proves the cell free of the *hull* points and argues the hidden ones are
behind them. :func:`obstacle_halfplanes` checks that for every sensed point (one vectorized
test) and gives any point no hyperplane excludes a hyperplane of its own, so no sensed point is
inside the cell and every one is at least ``r`` from it by construction. (In 2-D this guard has
never fired in 200,000 random clouds; it costs one matrix product.)

If the robot is closer than ``r`` to a sensed point or than ``2 r`` to a neighbour (tracking
error, a lidar seeing a corner late), the cell of Eq. 7 would be empty; the buffer is then
shrunk to half the clearance so that the cell still contains the robot and it can back off.

All points are ``(N, 2) float64`` [m] in the map frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection, QhullError

from coverage_ros.errors import ConfigError

#: Sides of the regular polygon inscribed in the sensing disc (area error 0.64 %).
DISC_SIDES = 32
#: Fraction of the clearance kept as buffer when the full buffer would empty the cell.
SHRUNK_BUFFER_FRACTION = 0.5
#: Hidden-point passes before every remaining point gets its own hyperplane (one or two suffice
#: in practice; the cap only bounds pathological clouds).
MAX_HIDDEN_PASSES = 8
#: [m] points closer than this to the robot centre are ignored (a range sensor cannot return
#: them; they would only produce a degenerate hyperplane).
MIN_POINT_DISTANCE = 1e-6
#: [m] an interior point must be this far inside every hyperplane for qhull (else the cell is
#: treated as empty: a sliver this thin carries no area worth moving into).
INTERIOR_MARGIN = 1e-9
#: [m] polygon vertices closer than this are one vertex.
VERTEX_MERGE = 1e-9


@dataclass(frozen=True)
class HalfPlanes:
    """Hyperplanes ``a' x <= b`` with buffers ``beta`` (cell side: ``a' x <= b - beta``)."""

    a: np.ndarray  # (K, 2) normals pointing away from the robot [1/m for obstacles, m for robots]
    b: np.ndarray  # (K,) offsets
    beta: np.ndarray  # (K,) buffers r |a|

    @staticmethod
    def empty() -> HalfPlanes:
        return HalfPlanes(np.zeros((0, 2)), np.zeros(0), np.zeros(0))

    def __len__(self) -> int:
        return len(self.b)

    def concat(self, other: HalfPlanes) -> HalfPlanes:
        return HalfPlanes(np.vstack([self.a, other.a]), np.concatenate([self.b, other.b]),
                          np.concatenate([self.beta, other.beta]))


@dataclass(frozen=True)
class BufferedCell:
    """The buffered Voronoi cell of Eq. 7 as a convex polygon."""

    polygon: np.ndarray  # (M, 2) [m] counter-clockwise; empty (0, 2) if the cell is empty
    obstacle_planes: HalfPlanes  # from the visible (and hidden-but-uncut) obstacle points
    robot_planes: HalfPlanes  # bisectors with the neighbours
    obstacle_points: np.ndarray  # (K,) indices into the given points, one per obstacle plane
    buffer: float  # [m] buffer actually used (the robot radius unless shrunk)
    disc_radius: float  # [m] radius of the sensing disc the cell was clipped to

    @property
    def planes(self) -> HalfPlanes:
        return self.obstacle_planes.concat(self.robot_planes)

    def contains(self, points: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """``(N,) bool``: points inside the polygon (convex, counter-clockwise)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if len(self.polygon) < 3:
            return np.zeros(len(pts), dtype=bool)
        e = np.roll(self.polygon, -1, axis=0) - self.polygon
        rel = pts[:, None, :] - self.polygon[None]
        cross = e[None, :, 0] * rel[..., 1] - e[None, :, 1] * rel[..., 0]
        inside: np.ndarray = np.all(cross >= -tol, axis=1)
        return inside


def spherical_flip(points: np.ndarray, center: np.ndarray, radius: float) -> np.ndarray:
    """Eq. 5: ``(N, 2)`` points mirrored about the circle of ``radius`` [m] around ``center``,
    relative to ``center`` (``|q'| = 2 R - |q - p|``)."""
    d = np.asarray(points, dtype=np.float64).reshape(-1, 2) - np.asarray(center, np.float64)
    n = np.hypot(d[:, 0], d[:, 1])
    return d + (2.0 * (radius - n) / np.maximum(n, MIN_POINT_DISTANCE))[:, None] * d


def visible_points(points: np.ndarray, center: np.ndarray, radius: float) -> np.ndarray:
    """``(K,) int64`` indices of the points on the convex hull of their spherical flip (with the
    origin), i.e. those that bound the free space seen from ``center``. Fewer than three points
    or a degenerate (collinear) cloud: all points."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 3:
        return np.arange(len(pts), dtype=np.int64)
    flipped = np.vstack([spherical_flip(pts, center, radius), np.zeros((1, 2))])
    try:
        hull = ConvexHull(flipped)
    except QhullError:
        return np.arange(len(pts), dtype=np.int64)
    v = np.asarray(hull.vertices, dtype=np.int64)
    return np.sort(v[v < len(pts)])


def eq6_hyperplane(point: np.ndarray, center: np.ndarray) -> tuple[np.ndarray, float]:
    """Eq. 6 for one obstacle point, in closed form: ``a = d / |d|^2`` (``d = q - p``), the
    minimum-norm ``a`` with ``d' a >= 1``, and the tight offset ``b = a' q``."""
    q = np.asarray(point, dtype=np.float64)
    d = q - np.asarray(center, dtype=np.float64)
    a = d / float(d @ d)
    return a, float(a @ q)


def _planes_for(points: np.ndarray, center: np.ndarray, buffer: float) -> HalfPlanes:
    """:func:`eq6_hyperplane` for ``(K, 2)`` points at once, with buffers ``beta = r |a|``."""
    d = points - center
    a = d / (d * d).sum(axis=1)[:, None]
    return HalfPlanes(a, (a * points).sum(axis=1), buffer * np.hypot(a[:, 0], a[:, 1]))


def robot_halfplanes(center: np.ndarray, neighbours: np.ndarray, buffer: float) -> HalfPlanes:
    """Eq. 4 for ``(J, 2)`` neighbour positions: bisector normals ``a = p_j - p_i`` with
    ``b = a' (p_i + p_j) / 2`` and ``beta = r |a|``."""
    nb = np.asarray(neighbours, dtype=np.float64).reshape(-1, 2)
    p = np.asarray(center, dtype=np.float64)
    a = nb - p
    keep = np.hypot(a[:, 0], a[:, 1]) > MIN_POINT_DISTANCE
    a, nb = a[keep], nb[keep]
    return HalfPlanes(a, (a * (0.5 * (p + nb))).sum(axis=1), buffer * np.hypot(a[:, 0], a[:, 1]))


def obstacle_halfplanes(points: np.ndarray, center: np.ndarray, radius: float, buffer: float,
                        extra: HalfPlanes | None = None) -> tuple[HalfPlanes, np.ndarray]:
    """Hyperplanes of Eq. 6 for the visible points among ``points (N, 2)`` (all within
    ``radius`` of ``center``), plus one for every point that none of them (nor the ``extra``
    hyperplanes, e.g. the bisectors) excludes. Returns the planes and the point indices."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    p = np.asarray(center, dtype=np.float64)
    if len(pts) == 0:
        return HalfPlanes.empty(), np.zeros(0, dtype=np.int64)
    chosen = visible_points(pts, p, radius)
    extra = extra if extra is not None else HalfPlanes.empty()
    for _ in range(MAX_HIDDEN_PASSES):
        planes = _planes_for(pts[chosen], p, buffer).concat(extra)
        # A point is cut off when it lies on or beyond some (unbuffered) hyperplane; then it is
        # at least the buffer away from the cell (Lemma 1, 5-6).
        cut = np.any(pts @ planes.a.T >= planes.b[None, :] * (1.0 - 1e-12), axis=1)
        cut[chosen] = True
        if cut.all():
            break
        chosen = np.union1d(chosen, np.flatnonzero(~cut))
    else:
        chosen = np.arange(len(pts), dtype=np.int64)
    return _planes_for(pts[chosen], p, buffer), chosen


def disc_halfplanes(center: np.ndarray, radius: float, sides: int = DISC_SIDES
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Edges of the regular ``sides``-gon inscribed in the circle, as ``(a (sides, 2), c)``
    with ``a' x <= c`` inside."""
    t = 2.0 * np.pi * (np.arange(sides) + 0.5) / sides
    a = np.stack([np.cos(t), np.sin(t)], axis=-1)
    return a, a @ np.asarray(center, dtype=np.float64) + radius * math.cos(math.pi / sides)


def halfplane_polygon(a: np.ndarray, c: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """``(M, 2)`` counter-clockwise polygon ``{x : a_k' x <= c_k}``, or ``(0, 2)`` if it has no
    interior. The region must be bounded (include the sensing disc's half-planes). ``hint`` is
    tried first as the interior point; otherwise the Chebyshev centre is found by linear
    programming."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    c = np.asarray(c, dtype=np.float64).reshape(-1)
    norm = np.hypot(a[:, 0], a[:, 1])
    inner = np.asarray(hint, dtype=np.float64).reshape(2)
    if np.min((c - a @ inner) / norm) <= INTERIOR_MARGIN:
        # Chebyshev centre: max t  s.t.  a_k' x + |a_k| t <= c_k.
        res = linprog(np.array([0.0, 0.0, -1.0]), A_ub=np.column_stack([a, norm]), b_ub=c,
                      bounds=[(None, None), (None, None), (0.0, None)], method="highs")
        if res.status != 0 or res.x[2] <= INTERIOR_MARGIN:
            return np.zeros((0, 2))
        inner = res.x[:2]
    try:
        hs = HalfspaceIntersection(np.column_stack([a, -c]), inner)
    except QhullError:
        return np.zeros((0, 2))
    pts = hs.intersections
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    order = np.argsort(np.arctan2(pts[:, 1] - inner[1], pts[:, 0] - inner[0]))
    pts = pts[order]
    # Drop repeated vertices (three or more lines through one point).
    keep = np.hypot(*(pts - np.roll(pts, 1, axis=0)).T) > VERTEX_MERGE
    pts = pts[keep] if keep.any() else pts[:1]
    return pts if len(pts) >= 3 else np.zeros((0, 2))


def buffered_cell(center: np.ndarray, obstacle_points: np.ndarray, neighbours: np.ndarray,
                  radius: float, sensor_radius: float,
                  bounds: tuple[float, float, float, float] | None = None) -> BufferedCell:
    """The buffered Voronoi cell (Eq. 7) of a robot of ``radius`` [m] at ``center``.

    ``obstacle_points (N, 2)`` are the sensed points (those farther than ``sensor_radius`` are
    ignored), ``neighbours (J, 2)`` the other robots' positions, ``bounds`` an optional
    ``(xmin, ymin, xmax, ymax)`` box the cell must stay in (the map).
    """
    if not (math.isfinite(radius) and radius > 0):
        raise ConfigError.at("robot radius", "must be a finite number > 0", radius)
    if not (math.isfinite(sensor_radius) and sensor_radius > radius):
        raise ConfigError.at("sensor_radius", "must exceed the robot radius", sensor_radius,
                             f"> {radius}")
    p = np.asarray(center, dtype=np.float64).reshape(2)
    pts = np.asarray(obstacle_points, dtype=np.float64).reshape(-1, 2)
    dist = np.hypot(*(pts - p).T) if len(pts) else np.zeros(0)
    keep = (dist <= sensor_radius) & (dist > MIN_POINT_DISTANCE)
    index = np.flatnonzero(keep)
    pts, dist = pts[keep], dist[keep]
    nb = np.asarray(neighbours, dtype=np.float64).reshape(-1, 2)
    # Lemma 1 needs |p - q| >= r and |p_i - p_j| >= 2 r; otherwise shrink the buffer so the
    # cell still contains the robot (see module docstring).
    buffer = radius
    if len(pts) and dist.min() <= radius:
        buffer = min(buffer, SHRUNK_BUFFER_FRACTION * float(dist.min()))
    half = 0.5 * float(np.hypot(*(nb - p).T).min()) if len(nb) else math.inf
    if half <= radius:
        buffer = min(buffer, SHRUNK_BUFFER_FRACTION * half)
    robots = robot_halfplanes(p, nb, buffer)
    obstacles, chosen = obstacle_halfplanes(pts, p, sensor_radius, buffer, extra=robots)
    disc_r = sensor_radius - radius
    da, dc = disc_halfplanes(p, disc_r)
    planes = obstacles.concat(robots)
    a, c = np.vstack([planes.a, da]), np.concatenate([planes.b - planes.beta, dc])
    if bounds is not None:
        xmin, ymin, xmax, ymax = bounds
        a = np.vstack([a, [[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]]])
        c = np.concatenate([c, [-xmin, xmax, -ymin, ymax]])
    poly = halfplane_polygon(a, c, p)
    return BufferedCell(poly, obstacles, robots, index[chosen], buffer, disc_r)


def convex_polygon_cells(polygon_grid: np.ndarray, shape: tuple[int, int]
                         ) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, cols)`` of the cells of an ``(H, W)`` grid whose centre ``(c + 0.5, r + 0.5)``
    lies in the convex polygon ``polygon_grid (M, 2)`` given in grid coordinates ``(gx, gy)``
    (scanline: one interval per row)."""
    H, W = shape
    poly = np.asarray(polygon_grid, dtype=np.float64).reshape(-1, 2)
    if len(poly) < 3:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    r_lo = max(int(math.ceil(poly[:, 1].min() - 0.5)), 0)
    r_hi = min(int(math.floor(poly[:, 1].max() - 0.5)), H - 1)
    if r_hi < r_lo:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    y = np.arange(r_lo, r_hi + 1) + 0.5
    a, b = poly, np.roll(poly, -1, axis=0)
    dy = b[:, 1] - a[:, 1]
    span = ((y[:, None] >= np.minimum(a[:, 1], b[:, 1])[None])
            & (y[:, None] <= np.maximum(a[:, 1], b[:, 1])[None]) & (dy != 0)[None])
    with np.errstate(divide="ignore", invalid="ignore"):
        x = a[None, :, 0] + (y[:, None] - a[None, :, 1]) * ((b[:, 0] - a[:, 0]) / dy)[None]
    xl = np.where(span, x, np.inf).min(axis=1)
    xr = np.where(span, x, -np.inf).max(axis=1)
    # Rows no edge spans (only by rounding at a vertex) get an empty interval.
    c_lo = np.where(np.isfinite(xl), np.maximum(np.ceil(xl - 0.5), 0), W).astype(np.int64)
    c_hi = np.where(np.isfinite(xr), np.minimum(np.floor(xr - 0.5), W - 1), -1).astype(np.int64)
    count = np.maximum(c_hi - c_lo + 1, 0)
    rows = np.repeat(np.arange(r_lo, r_hi + 1), count)
    start = np.repeat(c_lo - np.concatenate([[0], np.cumsum(count)[:-1]]), count)
    cols = start + np.arange(int(count.sum()))
    return rows, cols
