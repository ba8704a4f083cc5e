"""How well a team has explored: its belief scored against the true map.

* ``explored_fraction`` - the share of the true free area reachable from the starts that the
  belief marks free (p <= ``FREE_BELOW``). Reachable: the truly free cells that a robot's body
  can cover, i.e. within its radius of the centres it can reach from a start (the configuration
  space component of the starts, grown by the radius);
* ``false_free`` - the share of the truly occupied cells that the belief marks free (cells that
  an obstacle only reaches into, which a lidar may rightly see partly free, do not count);
* ``explored_at`` - the first time the explored fraction reached 0.5, 0.9, 0.95 and 0.99.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from coverage_ros.core.exploration.belief import BeliefSnapshot
from coverage_ros.core.exploration.maps import FREE_BELOW
from coverage_ros.core.world.grid import GridMap

#: Explored fractions whose first time is reported.
MILESTONES = (0.5, 0.9, 0.95, 0.99)


@dataclass(frozen=True)
class ExplorationScore:
    explored_fraction: float
    false_free: float


class ExplorationScorer:
    """Scores beliefs on one true map for one team's starts (the reachable area is computed
    once)."""

    def __init__(self, truth: GridMap, starts: np.ndarray, robot_radius: float,
                 solid: np.ndarray | None = None) -> None:
        self.truth = truth
        free = truth.free_mask()
        cspace = truth.inflated_free_mask(robot_radius)
        labels, _ = ndimage.label(cspace, structure=np.ones((3, 3)))
        cells = truth.world_to_cell(np.asarray(starts, dtype=np.float64)[:, :2])
        ok = truth.contains_cell(cells)
        ids = {int(labels[r, c]) for r, c in cells[ok]} - {0}
        reach = np.isin(labels, list(ids)) if ids else np.zeros(truth.shape, bool)
        # Grow the centres' region by the radius: the body reaches that far.
        dist = ndimage.distance_transform_edt(~reach) * truth.resolution
        self.reachable = free & (dist <= robot_radius + 0.5 * truth.resolution)
        # Cells an obstacle only reaches into may rightly be seen partly free: the false free
        # share counts the cells occupied for certain (``solid``, see WorldSpec.solid).
        self.occupied = truth.occupied_mask(unknown_is_occupied=False) if solid is None \
            else solid
        self.reachable_cells = int(self.reachable.sum())

    def score(self, snapshot: BeliefSnapshot) -> ExplorationScore:
        if snapshot.lattice.shape != self.truth.shape:
            raise ValueError("belief and true map have different shapes: "
                             f"{snapshot.lattice.shape} vs {self.truth.shape}")
        seen_free = snapshot.observed & (snapshot.probability <= FREE_BELOW)
        explored = float((seen_free & self.reachable).sum()) / max(self.reachable_cells, 1)
        wrong = float((seen_free & self.occupied).sum()) / max(int(self.occupied.sum()), 1)
        return ExplorationScore(explored, wrong)


def milestones(times: Sequence[float] | np.ndarray, fractions: Sequence[float] | np.ndarray,
               levels: Sequence[float] = MILESTONES) -> dict[str, float | None]:
    """First time each level of explored fraction was reached (None: never)."""
    out: dict[str, float | None] = {}
    f = np.asarray(fractions, dtype=np.float64)
    t = np.asarray(times, dtype=np.float64)
    for level in levels:
        hit = np.flatnonzero(f >= level)
        out[f"{level:g}"] = round(float(t[hit[0]]), 2) if len(hit) else None
    return out
