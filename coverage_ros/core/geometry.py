"""Small vectorized 2-D geometry helpers (points are ``(N, 2) float64`` arrays, metres)."""

from __future__ import annotations

import numpy as np


def wrap_angle(a: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles [rad] to ``[-pi, pi)``."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def points_in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """``(N,) bool``: even-odd rule point-in-polygon test for a simple polygon ``(M, 2)``.

    >>> square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    >>> points_in_polygon(np.array([[0.5, 0.5], [1.5, 0.5]]), square).tolist()
    [True, False]
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    poly = np.asarray(polygon, dtype=np.float64)
    x, y = pts[:, 0:1], pts[:, 1:2]
    x0, y0 = poly[:, 0], poly[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    straddles = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    crossings = straddles & (x < x_cross)
    counts: np.ndarray = np.count_nonzero(crossings, axis=1)
    return (counts % 2).astype(bool)


def distance_to_segments(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(N,)``: distance from each point to the nearest of the segments ``a[k] -> b[k]``
    (``a``, ``b`` are ``(M, 2)``)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 1, 2)
    a = np.asarray(a, dtype=np.float64)[None]
    ab = np.asarray(b, dtype=np.float64)[None] - a
    denom = np.maximum((ab * ab).sum(-1), 1e-300)
    t = np.clip(((pts - a) * ab).sum(-1) / denom, 0.0, 1.0)
    closest = a + t[..., None] * ab
    dist: np.ndarray = np.sqrt(((pts - closest) ** 2).sum(-1)).min(axis=1)
    return dist


def polygon_edges(polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points ``(M, 2)`` of a closed polygon's edges."""
    poly = np.asarray(polygon, dtype=np.float64)
    return poly, np.roll(poly, -1, axis=0)


def polygon_area(polygon: np.ndarray) -> float:
    """Signed area (shoelace formula; positive for counter-clockwise vertices)."""
    p = np.asarray(polygon, dtype=np.float64)
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def box_polygon(center: np.ndarray, size: np.ndarray, yaw: float = 0.0) -> np.ndarray:
    """``(4, 2)`` counter-clockwise corners of a rotated rectangle."""
    hw, hh = 0.5 * float(size[0]), 0.5 * float(size[1])
    corners = np.array([[-hw, -hh], [hw, -hh], [hw, hh], [-hw, hh]])
    c, s = np.cos(yaw), np.sin(yaw)
    rotated: np.ndarray = corners @ np.array([[c, s], [-s, c]])
    return rotated + np.asarray(center, dtype=np.float64)


def segment_polygon(start: np.ndarray, end: np.ndarray, thickness: float) -> np.ndarray:
    """``(4, 2)`` rectangle of the given thickness around a segment (a wall)."""
    start = np.asarray(start, dtype=np.float64)
    end = np.asarray(end, dtype=np.float64)
    d = end - start
    length = float(np.hypot(*d))
    yaw = float(np.arctan2(d[1], d[0])) if length > 0 else 0.0
    return box_polygon(0.5 * (start + end), np.array([length + thickness, thickness]), yaw)
