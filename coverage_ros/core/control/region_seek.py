"""Heading for a region of interest that the robot's own cell does not reach.

With a region of interest (:class:`~coverage_ros.core.world.region.Region`) the density is zero
outside it. A robot whose cell holds none of the region (the others' cells cover it) would stay
where it is, its Lloyd control zero; :func:`seek_region` sends it to the region's nearest point
along the map's paths instead, until its cell holds some of it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies import Decision
from coverage_ros.core.world.region import Region

#: A cell with less than this share of the domain's mass is empty.
EMPTY_CELL = 1e-6


def seek_region(domain: CoverageDomain, region: Region, decision: Decision,
                pose: np.ndarray) -> Decision:
    """``decision``, or - when the robot at ``pose`` steers by goals and its cell is empty
    while ``region`` is not everywhere - a decision to go to the region's nearest point
    (mode ``seek``, not converged); unchanged when no point of the region can be reached."""
    if region.everywhere or decision.velocity is not None or \
            decision.mass > EMPTY_CELL * float(domain.mass_element.sum()):
        return decision
    nodes, _, _ = domain.snap(pose[:2])
    if len(nodes) == 0:
        return decision
    dist = dijkstra(domain.graph.csr, directed=True, indices=nodes, min_only=True)
    dist[domain.density.ravel() <= 0] = np.inf
    k = int(np.argmin(dist))
    if not np.isfinite(dist[k]):
        return decision
    target = domain.to_map(domain.node_centers(np.array([k])))[0]
    return replace(decision, goal=target, target=target, mode="seek", converged=False)
