"""What a belief becomes for planning: the map robots navigate on, and the entropy-weighted
coverage domain of Bhattacharya et al. (2014, Sec. 4.2, Eq. 9).

* :func:`belief_grid` - the belief as an occupancy grid in the ROS convention: -1 where nothing
  was seen, else round(100 p). A vertex is inaccessible where p >= 0.65 (map_server's
  ``occupied_thresh``, the grid convention's ``OCCUPIED_PERCENT``); everything else - seen free,
  undecided or never seen - is accessible.
* :func:`navigation_domain` - the configuration space robots plan and check their commands on:
  inaccessible cells inflated by the robot radius; unknown space is traversable but costs
  ``UNKNOWN_COST`` times its length, so paths keep to known free space where they can (the
  lidar-based safety filter still has the last word).
* :func:`entropy_domain` - the geodesic power Voronoi domain of the paper: with the entropy e(q)
  of the belief, the density and the isotropic metric zeta I are (Eq. 9) ::

      w(q) = eps_w if e(q) < tau else e(q),      zeta(q) = eps_zeta if e(q) < tau else e(q)

  so unexplored regions are "stretched out" and weigh more, and explored ones nearly vanish.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.exploration.belief import BeliefSnapshot
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError

#: A cell counts as seen free when its occupancy probability is at most this (the order of
#: map_server's free_thresh): explored maps written by the stack, the explored fraction and the
#: frontier baseline all use it.
FREE_BELOW = 0.25
#: ... and as occupied when at least this (map_server's occupied_thresh).
OCCUPIED_FROM = 0.65
#: Path length factor through unknown (or undecided) space for navigation: twice as long as
#: through space seen free, so a robot takes a known corridor over a short cut into the dark.
UNKNOWN_COST = 2.0
#: [nats] cells below this entropy count as known for navigation costs (p < 0.24 or > 0.76).
KNOWN_ENTROPY = 0.55


@dataclass(frozen=True)
class EntropyMetric:
    """Eq. 9's thresholds (Bhattacharya et al. 2014 give no values; these are ours)."""

    tau: float = 0.55  # [nats] vertices above this entropy are unexplored (p in (0.24, 0.76))
    eps_w: float = 0.01  # density of explored vertices ("representing zero")
    eps_zeta: float = 0.1  # metric weight of explored vertices (lengths x sqrt(0.1) = 0.32)

    def __post_init__(self) -> None:
        if not 0.0 < self.tau < math.log(2.0):
            raise ConfigError.at("tau", "must be in (0, ln 2) nats", self.tau)
        for name in ("eps_w", "eps_zeta"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0.0 < v < self.tau):
                raise ConfigError.at(name, "must be a number in (0, tau)", v,
                                     f"0 < {name} < tau = {self.tau}")

    def weights(self, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(w, zeta)`` of Eq. 9 for entropies ``e`` [nats]."""
        unexplored = e >= self.tau
        return (np.where(unexplored, e, self.eps_w), np.where(unexplored, e, self.eps_zeta))


def belief_grid(snapshot: BeliefSnapshot) -> GridMap:
    """The belief as an occupancy grid: -1 never seen, else round(100 p)."""
    occ = np.rint(100.0 * snapshot.probability).astype(np.int8)
    occ[~snapshot.observed] = -1
    return snapshot.lattice.with_occupancy(occ)


def _entropy(snapshot: BeliefSnapshot) -> np.ndarray:
    if "entropy" not in snapshot.derived:
        snapshot.derived["entropy"] = snapshot.entropy
    e: np.ndarray = snapshot.derived["entropy"]
    return e


def trinary_grid(snapshot: BeliefSnapshot) -> GridMap:
    """The belief as map_server would save it: 0 free (p <= FREE_BELOW), 100 occupied
    (p >= OCCUPIED_FROM), -1 otherwise."""
    p = snapshot.probability
    occ = np.full(p.shape, -1, np.int8)
    occ[snapshot.observed & (p <= FREE_BELOW)] = 0
    occ[snapshot.observed & (p >= OCCUPIED_FROM)] = 100
    return snapshot.lattice.with_occupancy(occ)


def navigation_domain(snapshot: BeliefSnapshot, robot_radius: float,
                      connectivity: int = 8) -> CoverageDomain:
    """The map to plan paths and check commands on (see module docstring); memoized in the
    snapshot."""
    key = ("navigation", float(robot_radius), connectivity)
    if key not in snapshot.derived:
        known = _entropy(snapshot) < KNOWN_ENTROPY
        zeta = np.where(known, 1.0, UNKNOWN_COST ** 2)
        snapshot.derived[key] = CoverageDomain.from_grid(
            belief_grid(snapshot), robot_radius, connectivity=connectivity,
            unknown_is_free=True, zeta=zeta)
    domain: CoverageDomain = snapshot.derived[key]
    return domain


def entropy_domain(snapshot: BeliefSnapshot, robot_radius: float, metric: EntropyMetric,
                   connectivity: int = 8, blocked: np.ndarray | None = None
                   ) -> tuple[CoverageDomain, np.ndarray]:
    """Eq. 9's coverage domain of the belief, and the ``(H, W)`` entropy it came from;
    memoized in the snapshot. ``blocked`` ``(H, W) bool``: cells taken as occupied whatever
    the belief says (a robot's given-up pockets); such a domain is not memoized."""
    key = ("entropy", float(robot_radius), metric, connectivity)
    e = _entropy(snapshot)
    if blocked is None and key in snapshot.derived:
        return snapshot.derived[key], e
    grid = belief_grid(snapshot)
    if blocked is not None:
        occ = grid.occupancy.copy()
        occ[blocked] = 100
        grid = grid.with_occupancy(occ)
    w, zeta = metric.weights(e)
    domain = CoverageDomain.from_grid(grid, robot_radius, connectivity=connectivity,
                                      unknown_is_free=True, zeta=zeta).with_density(w)
    if blocked is None:
        snapshot.derived[key] = domain
    return domain, e
