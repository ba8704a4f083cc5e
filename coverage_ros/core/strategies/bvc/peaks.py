"""Peaks of the importance density that no robot attends (this project's extension of Wang et
al.'s guided map).

Wang et al. guide a robot to the local maximum of the density within its sensing range. Where
two robots reach the same peak, the one whose Voronoi region holds it keeps it and the other
settles at the border of its region nearest to it - beside its neighbour, while a peak beyond
both robots' sensing ranges stays uncovered (in our re-drawn Table I, 3 robots on 3 peaks, the
peak missed in most failed trials). The density is the map's prior ("GIS prior"), known to
every robot, and so are its neighbours' positions: a robot with no peak of its own in range
is matched to one that no robot is within sensing range of (:func:`peak_role`; every robot
computes the same matching from the same positions), and a robot left with neither a peak to
keep nor one to seek covers round the others, with Lloyd's centroid under the importance
density instead of a guide to the border of its region.

A *peak* is a free cell whose density is the largest within a square window of one sensing
radius on each side and strictly above the smallest of the free cells there (the top of a
bump, not a flat map), and at least :data:`PEAK_SHARE` of the largest density (not a ripple
of a tail); a few tied cells are one peak, many (a plateau, an area of equal importance) none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.optimize import linear_sum_assignment

from coverage_ros.core.geodesic.domain import CoverageDomain

#: A peak's density is at least this share of the map's largest.
PEAK_SHARE = 0.05
#: Most tied cells a peak's top may have (a top between cell centres ties up to four).
TOP_CELLS = 9


def density_peaks(domain: CoverageDomain, radius: float) -> np.ndarray:
    """``(K, 2)`` [m] the peaks of ``domain``'s density (module docstring) for a window of
    ``radius`` [m] on each side of a cell."""
    w = domain.density
    top = float(w.max()) if w.size else 0.0
    if top <= 0.0:
        return np.zeros((0, 2))
    size = 2 * max(int(math.ceil(radius / domain.resolution)), 1) + 1
    free = domain.free
    is_max = w >= ndimage.maximum_filter(w, size=size, mode="nearest")
    # (the least over free cells only: a wall's zero density does not make a bump)
    not_flat = w > ndimage.minimum_filter(np.where(free, w, np.inf), size=size,
                                          mode="nearest")
    labels, count = ndimage.label(is_max & not_flat & (w >= PEAK_SHARE * top) & free,
                                  structure=np.ones((3, 3)))
    if count == 0:
        return np.zeros((0, 2))
    # A top that falls between cell centres is a few tied cells: one peak, at their middle.
    # More tied cells than TOP_CELLS are a plateau (an area of equal importance), no peak.
    rows, cols = np.nonzero(labels)
    index = labels[rows, cols] - 1
    xy = domain.to_map(domain.node_centers(rows * domain.shape[1] + cols))
    sums = np.zeros((count, 2))
    np.add.at(sums, index, xy)
    cells = np.bincount(index, minlength=count)
    small = cells <= TOP_CELLS
    return sums[small] / cells[small, None]


@dataclass(frozen=True)
class PeakRole:
    """What a robot does about the density's peaks (:func:`peak_role`)."""

    owns: bool  # it is the nearest robot to an attended peak: it keeps it
    target: np.ndarray | None  # (2,) [m] the unattended peak it is matched to, if any

    @property
    def peakless(self) -> bool:
        """Neither owner nor matched: it covers around the others (Lloyd in its cell)."""
        return not self.owns and self.target is None


def peak_role(position: np.ndarray, peaks: np.ndarray, neighbours: np.ndarray,
              reach: float) -> PeakRole:
    """The robot at ``position``'s role among ``peaks (K, 2)``, ``K >= 1``.

    A peak is attended when the robot nearest to it (its Voronoi owner among the robot and
    ``neighbours (J, 2)``) is within ``reach`` [m]; the owners of attended peaks keep them.
    The other robots are matched to the unattended peaks so that the summed straight-line
    distance is least (scipy's ``linear_sum_assignment``: the same matching on every robot,
    which all see the same positions) - a far robot is not left the farthest peak because a
    nearer one took the closest pair first."""
    team = np.vstack([np.asarray(position, np.float64)[None, :], neighbours.reshape(-1, 2)])
    d = np.hypot(peaks[:, None, 0] - team[None, :, 0], peaks[:, None, 1] - team[None, :, 1])
    owner = np.argmin(d, axis=1)
    attended = d[np.arange(len(peaks)), owner] <= reach
    busy = np.zeros(len(team), dtype=bool)
    busy[owner[attended]] = True
    if busy[0] or attended.all():
        return PeakRole(bool(busy[0]), None)
    open_peaks, idle = np.flatnonzero(~attended), np.flatnonzero(~busy)
    rows, cols = linear_sum_assignment(d[np.ix_(open_peaks, idle)])
    mine = rows[idle[cols] == 0]
    return PeakRole(False, peaks[open_peaks[mine[0]]].copy() if len(mine) else None)
