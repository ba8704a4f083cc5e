"""What a bvc robot remembers of its scans (Wang et al. 2024, Sec. IV-C): where its range sensor
has hit something (:class:`ObstacleMemory`, a map-aligned boolean grid; never-seen space counts
as free, as in the paper) and, under a flat density (this project's extension), the cells its
scans saw free, with the shadows of narrow obstacles bridged (:func:`bridge_shadows`).

Coordinates: points ``(N, 2) float64`` [m] map frame; memory cells ``(row, col)`` with row 0 at
the lowest y, cell ``(r, c)`` covering ``origin + res * ([c, c + 1] x [r, r + 1])``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from coverage_ros.errors import ConfigError


@dataclass
class ObstacleMemory:
    """Cells in which the robot's sensor has returned a hit, and cells it has seen free (mutable,
    one per robot)."""

    origin: np.ndarray  # (2,) [m] lower-left corner of cell (0, 0), map frame
    resolution: float  # [m] cell side
    hits: np.ndarray  # (H, W) bool
    seen: np.ndarray | None = None  # (H, W) bool: centre seen free by some scan (None: none)

    @classmethod
    def covering(cls, extent: tuple[float, float, float, float],
                 resolution: float) -> ObstacleMemory:
        """An empty memory covering ``extent = (xmin, ymin, xmax, ymax)`` [m]."""
        if not (math.isfinite(resolution) and resolution > 0):
            raise ConfigError.at("grid_resolution", "must be a finite number > 0 [m]",
                                 resolution)
        xmin, ymin, xmax, ymax = extent
        W = max(int(math.ceil((xmax - xmin) / resolution)), 1)
        H = max(int(math.ceil((ymax - ymin) / resolution)), 1)
        return cls(np.array([xmin, ymin], dtype=np.float64), float(resolution),
                   np.zeros((H, W), dtype=bool))

    @property
    def shape(self) -> tuple[int, int]:
        H, W = self.hits.shape
        return H, W

    def cells(self, points: np.ndarray) -> np.ndarray:
        """``(N, 2) int64`` cells ``(row, col)`` of points (may lie off the grid)."""
        g = np.floor((np.asarray(points, np.float64).reshape(-1, 2) - self.origin)
                     / self.resolution).astype(np.int64)
        return np.stack([g[:, 1], g[:, 0]], axis=-1)

    def centers(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """``(N, 2)`` [m] centres of cells ``(rows, cols)``."""
        return self.origin + self.resolution * (np.stack([cols, rows], axis=-1) + 0.5)

    def add(self, points: np.ndarray) -> None:
        """Mark the cells of ``points (N, 2)`` as hit (points off the grid are ignored)."""
        rc = self.cells(points)
        H, W = self.shape
        ok = (rc[:, 0] >= 0) & (rc[:, 0] < H) & (rc[:, 1] >= 0) & (rc[:, 1] < W)
        self.hits[rc[ok, 0], rc[ok, 1]] = True

    def add_view(self, position: np.ndarray, reach: float,
                 sees: Callable[[np.ndarray], np.ndarray]) -> None:
        """Mark the cells within ``reach`` [m] of ``position`` whose centres ``sees`` (a
        scan's :meth:`~coverage_ros.core.strategies.base.Scan.sees` at its pose: ``(N, 2)``
        points -> ``(N,) bool``) reports free."""
        if self.seen is None:
            self.seen = np.zeros_like(self.hits)
        H, W = self.shape
        rc = self.cells(np.asarray(position, np.float64))[0]
        n = int(math.ceil(reach / self.resolution)) + 1
        r0, r1 = max(int(rc[0]) - n, 0), min(int(rc[0]) + n + 1, H)
        c0, c1 = max(int(rc[1]) - n, 0), min(int(rc[1]) + n + 1, W)
        if r0 >= r1 or c0 >= c1:
            return
        rows, cols = np.mgrid[r0:r1, c0:c1]
        xy = self.centers(rows.ravel(), cols.ravel())
        near = np.hypot(*(xy - position).T) <= reach
        free = np.zeros(len(xy), dtype=bool)
        free[near] = sees(xy[near])
        self.seen[r0:r1, c0:c1] |= free.reshape(rows.shape)

    def was_seen(self, points: np.ndarray) -> np.ndarray:
        """``(N,) bool``: whether the cells of ``points (N, 2)`` were ever seen free."""
        rc = self.cells(points)
        H, W = self.shape
        ok = (rc[:, 0] >= 0) & (rc[:, 0] < H) & (rc[:, 1] >= 0) & (rc[:, 1] < W)
        out = np.zeros(len(rc), dtype=bool)
        if self.seen is not None:
            out[ok] = self.seen[rc[ok, 0], rc[ok, 1]]
        return out


def bridge_shadows(depths: np.ndarray, angle_increment: float, width: float,
                   full_circle: bool) -> np.ndarray:
    """Per-beam free depths ``(B,)`` [m] of a scan with the shadows of narrow obstacles filled
    in: a beam that stopped on an obstacle narrower than ``width`` [m] - one with a farther
    return within that width's angle on *both* sides (``atan(width / depth)`` at the beam's
    own depth, at most a quarter turn) - counts as free as far as the nearer of the two
    sides' farthest returns. A pillar or a teammate in front of open space then hides none of
    it, while a wall (no far return on one side) or an opening beside a wall stays as it is.
    Depths never get smaller; invalid beams (depth 0) stay 0; with ``full_circle`` the beams
    wrap round, otherwise the scan's edges have no far side."""
    depth = np.asarray(depths, dtype=np.float64)
    B = len(depth)
    if width <= 0 or B < 3 or not np.any(depth > 0):
        return depth.copy()
    window = np.ceil(np.arctan2(width, np.maximum(depth, 1e-9)) / angle_increment)
    K = max(min(int(window.max()), B // 4), 1)
    window = np.minimum(window, K).astype(np.int64)
    left, right = np.full(B, -np.inf), np.full(B, -np.inf)  # farthest within j beams
    left_far, right_far = np.zeros(B), np.zeros(B)  # ... within each beam's own window
    never = np.full(K, -np.inf)
    for j in range(1, K + 1):
        if full_circle:
            np.maximum(left, np.roll(depth, j), out=left)
            np.maximum(right, np.roll(depth, -j), out=right)
        else:
            np.maximum(left, np.concatenate([never[:j], depth[:-j]]), out=left)
            np.maximum(right, np.concatenate([depth[j:], never[:j]]), out=right)
        at = window == j
        left_far[at], right_far[at] = left[at], right[at]
    bridged = np.maximum(depth, np.minimum(left_far, right_far))
    return np.where(depth > 0, bridged, depth)
