"""Where a robot may be put: checks of requested poses and random free placement."""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from coverage_ros.core.world import CLUSTER_GAP, CLUSTER_WALL_MARGIN, WorldSpec
from coverage_ros.errors import WorldError

PLACEMENT_TRIES = 500  # random free cells tried before giving up (each try is a cheap check)

Pose = tuple[float, float, float]


class FreePlacer:
    """Free-space checks and random placement in the largest connected free region."""

    def __init__(self, spec: WorldSpec) -> None:
        self.spec = spec
        self._pools: dict[float, np.ndarray] = {}

    def check(self, pose: Pose, radius: float, others: list[tuple[float, float, float]],
              where: str) -> Pose:
        """Return ``pose`` if a robot of ``radius`` fits there; raise :class:`WorldError`
        naming ``where`` otherwise. ``others`` are ``(x, y, radius)`` of robots present."""
        if len(pose) != 3 or not all(math.isfinite(v) for v in pose):
            raise WorldError.at(where, "must be three finite numbers [x, y, yaw]", pose)
        x, y, yaw = pose
        grid = self.spec.grid
        if not grid.contains_point(np.array([[x, y]]))[0]:
            xmin, ymin, xmax, ymax = grid.extent()
            raise WorldError.at(where, "is outside the map", (x, y),
                                f"x in [{xmin:g}, {xmax:g}], y in [{ymin:g}, {ymax:g}]")
        clearance = self.spec.start_clearance(x, y)
        if clearance < radius:
            raise WorldError.at(where, f"({x:g}, {y:g}) is inside an obstacle or wall "
                                f"(clearance {clearance:.3f} m < robot radius {radius:g} m)")
        for ox, oy, r in others:
            if math.hypot(x - ox, y - oy) < radius + r:
                raise WorldError.at(where, f"({x:g}, {y:g}) overlaps the robot at "
                                    f"({ox:.2f}, {oy:.2f})")
        return (x, y, yaw)

    def _pool(self, radius: float) -> np.ndarray:
        """``(K, 2)`` [m] centres of free cells, in the largest region, for this radius."""
        pool = self._pools.get(radius)
        if pool is None:
            grid = self.spec.grid
            free = grid.inflated_free_mask(radius + CLUSTER_WALL_MARGIN)
            labels, n = ndimage.label(free, structure=np.ones((3, 3)))
            if n == 0:
                pool = np.zeros((0, 2))
            else:
                biggest = int(np.argmax(np.bincount(labels.ravel())[1:])) + 1
                pool = grid.cell_centers(np.argwhere(labels == biggest))
            self._pools[radius] = pool
        return pool

    def place(self, radius: float, others: list[tuple[float, float, float]],
              rng: np.random.Generator) -> Pose:
        """A random free pose for a robot of ``radius`` [m], at least ``CLUSTER_GAP`` from the
        robots ``others`` ``(x, y, radius)``; raises :class:`WorldError` if none is found."""
        pool = self._pool(radius)
        if len(pool):
            picks = pool[rng.integers(0, len(pool), size=PLACEMENT_TRIES)]
            yaws = rng.uniform(-math.pi, math.pi, size=PLACEMENT_TRIES)
            ok = np.ones(PLACEMENT_TRIES, dtype=bool)
            if others:
                o = np.asarray(others, dtype=np.float64)
                d = np.hypot(picks[:, None, 0] - o[:, 0], picks[:, None, 1] - o[:, 1])
                ok = (d >= o[:, 2] + radius + CLUSTER_GAP).all(axis=1)
            for k in np.flatnonzero(ok):
                x, y = float(picks[k, 0]), float(picks[k, 1])
                if self.spec.start_clearance(x, y) >= radius:
                    return (x, y, float(yaws[k]))
        raise WorldError.at("spawn", f"no free place found for a robot of radius {radius:g} m "
                            f"after {PLACEMENT_TRIES} tries")
