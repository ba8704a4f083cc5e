"""Frontiers of an occupancy belief, found and ranked the way explore_lite does it
(``frontier_search.cpp`` of m-explore / m-explore-ros2).

A cell is *free* when the belief is sure enough of it (p <= ``FREE_BELOW``, the free threshold
of the maps the stack writes) and a robot's centre may stand there (the configuration space;
explore_lite searches its costmap's zero-cost cells, which excludes the inflated zone around
obstacles); *unknown* when it is neither free nor occupied (p >= 0.65). A *frontier cell* is an
unknown cell with a free cell among its 4 neighbours. explore_lite searches breadth-first from
the robot's nearest free cell over the free cells (4-connected) and grows a frontier from every
frontier cell it meets over the 8-connected frontier cells; here the same sets come from
connected-component labelling (:mod:`scipy.ndimage`): the free region connected to the robot,
and the 8-connected clusters of frontier cells that border it.

Each frontier has its ``size`` [cells], ``centroid`` and ``middle`` (its cell nearest to the
robot) [m], ``min_distance`` [m] (straight-line distance from the robot's cell to that nearest
cell) and the cost explore_lite ranks them by (its ``frontierCost``, including that it
multiplies the distance, already in metres, by the map resolution once more)::

    cost = potential_scale * min_distance * resolution - gain_scale * size * resolution

Frontiers shorter than ``min_frontier_size`` [m] (size * resolution) are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from coverage_ros.core.exploration.belief import BeliefSnapshot
from coverage_ros.core.exploration.maps import FREE_BELOW, OCCUPIED_FROM
from coverage_ros.core.world.grid import GridMap

FOUR = ndimage.generate_binary_structure(2, 1)
EIGHT = ndimage.generate_binary_structure(2, 2)


@dataclass(frozen=True)
class Frontier:
    size: int  # [cells]
    centroid: np.ndarray  # (2,) [m]
    middle: np.ndarray  # (2,) [m] the frontier cell nearest to the robot
    min_distance: float  # [m]
    cost: float
    cells: np.ndarray  # (size,) flat indices


def classify(snapshot: BeliefSnapshot, robot_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """``(free, unknown)`` ``(H, W) bool`` masks (see module docstring)."""
    p = snapshot.probability
    occupied = snapshot.observed & (p >= OCCUPIED_FROM)
    known_free = snapshot.observed & (p <= FREE_BELOW)
    grid = GridMap(np.where(occupied, 100, 0).astype(np.int8), snapshot.lattice.resolution,
                   snapshot.lattice.origin)
    free = known_free & grid.inflated_free_mask(robot_radius)
    unknown = ~occupied & ~known_free
    return free, unknown


def find_frontiers(snapshot: BeliefSnapshot, position: np.ndarray, robot_radius: float,
                   potential_scale: float = 3.0, gain_scale: float = 1.0,
                   min_frontier_size: float = 0.75) -> list[Frontier]:
    """The frontiers reachable from ``position`` (2,) [m], cheapest first."""
    lattice = snapshot.lattice
    res = lattice.resolution
    H, W = lattice.shape
    free, unknown = classify(snapshot, robot_radius)
    if not free.any():
        return []
    # 1. The free region the robot can reach: the 4-connected component of its nearest free
    #    cell (explore_lite's breadth-first search).
    cell = lattice.world_to_cell(np.asarray(position, dtype=np.float64)[None])[0]
    cell = np.clip(cell, 0, [H - 1, W - 1])
    _, (rr, cc) = ndimage.distance_transform_edt(~free, return_indices=True)
    start = (rr[cell[0], cell[1]], cc[cell[0], cell[1]])
    labels, _ = ndimage.label(free, structure=FOUR)
    region = labels == labels[start]
    # 2. Frontier cells: unknown, with a free 4-neighbour; clusters: 8-connected; kept if they
    #    border the reached region.
    frontier_cells = unknown & ndimage.binary_dilation(free, structure=FOUR)
    clusters, n = ndimage.label(frontier_cells, structure=EIGHT)
    if n == 0:
        return []
    touching = np.unique(clusters[ndimage.binary_dilation(region, structure=FOUR)
                                  & frontier_cells])
    # 3. Per cluster: size, centroid, nearest cell, cost.
    reference = lattice.cell_centers(np.array([cell]))[0]
    flat = clusters.ravel()
    members = np.flatnonzero(np.isin(flat, touching[touching > 0]))
    members = members[np.argsort(flat[members], kind="stable")]
    bounds = np.flatnonzero(np.diff(flat[members])) + 1
    out: list[Frontier] = []
    for idx in np.split(members, bounds):
        size = len(idx)
        if size == 0:
            continue
        if size * res < min_frontier_size:
            continue
        rows, cols = np.divmod(idx, W)
        xy = lattice.cell_centers(np.stack([rows, cols], axis=-1))
        d = np.hypot(*(xy - reference).T)
        j = int(np.argmin(d))
        cost = potential_scale * float(d[j]) * res - gain_scale * size * res
        out.append(Frontier(size, xy.mean(axis=0), xy[j].copy(), float(d[j]), cost, idx))
    out.sort(key=lambda f: f.cost)
    return out
