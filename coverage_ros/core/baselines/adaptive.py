"""Coverage with a repulsive density around detected obstacles, local sensing - the second
baseline of Wang et al. (2024, Table I, "Adaptive [9]").

Source: Y. Bai, Y. Wang, X. Xiong, M. Svinin and E. Magid, "Adaptive multiagent control with
dynamic obstacle avoidance in a limited region", American Control Conference 2022, pp.
4695-4700. Neither the paper nor its equations could be found in any public source available to
us (only its title and Wang et al.'s account of it), so this module implements what that account
states and no more:

* a Voronoi-based (Lloyd) coverage method with **local sensing** (Wang et al., Table I): the
  robot knows the obstacles within its sensing radius and works in its Voronoi cell limited to
  its sensing disc (the "limited region");
* it "utilizes a repulsive density function concerning detected obstacles, ensuring that the
  newly computed centroid is positioned away from the obstacle" (Sec. V-B): the density of the
  cell combines the attractive importance density (ToI coverage) and repulsive fields of the
  detected obstacles (their Fig. 8 b), which shrinks the space a robot moves in;
* obstacles are circles, as for OAVC (Wang et al.: "the obstacles are modeled as the same
  shape").

**Our choices, where the source is silent** (so a reader can weigh the row): the repulsive field
of an obstacle is a Gaussian of the distance ``g`` to its boundary, scaled to the local
importance, ``phi_rep(q) = phi(q) exp(-g^2 / (2 sigma^2))``, and the fields add:
``phi_total(q) = max(phi(q) - sum_k phi_rep,k(q), 0) = phi(q) max(1 - sum_k exp(-g_k^2 /
(2 sigma^2)), 0)`` (:func:`repulsive_weight`) - zero on an obstacle's boundary, the importance
density far from every obstacle; ``sigma`` is :attr:`AdaptiveParams.repulsion_sigma`. The cell
is the buffered Voronoi cell (robots are discs; Zhou et al. 2017) within the sensing disc and
the arena. Not implemented: the *adaptive* law of the title (online estimation of unknown
density parameters, as in Schwager et al.'s adaptive coverage) - in Wang et al.'s comparison the
target density is given to every method - and any avoidance mechanism beyond the density: the
robot moves straight to the centroid (Eq. 3 of Wang et al.), so a centroid beyond an obstacle
can take it into the obstacle, and the trial counts that collision.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from coverage_ros.core.baselines.common import (
    Circles,
    LloydParams,
    MoveToCentroid,
    buffered_voronoi,
)
from coverage_ros.core.strategies.base import Decision, Neighbour, Observation
from coverage_ros.core.strategies.bvc.cells import disc_halfplanes, halfplane_polygon
from coverage_ros.errors import ConfigError


@dataclass(frozen=True)
class AdaptiveParams(LloydParams):
    """Settings of the adaptive baseline."""

    #: [m] spread of an obstacle's repulsive field (ours: Bai et al.'s is unknown); at this
    #: distance from the boundary the importance keeps 39 % of its value, at 2 sigma 86 %.
    repulsion_sigma: float = 0.5

    def __post_init__(self) -> None:
        super().__post_init__()
        v = self.repulsion_sigma
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                or v <= 0:
            raise ConfigError.at("adaptive.repulsion_sigma", "must be a finite number > 0", v)


def repulsive_weight(points: np.ndarray, circles: Circles, sigma: float) -> np.ndarray:
    """``(N,)`` in ``[0, 1]``: the share of the importance density left at ``points (N, 2)``
    [m] by the repulsive fields of ``circles`` of spread ``sigma`` [m], ``max(1 - sum_k
    exp(-g_k^2 / (2 sigma^2)), 0)`` with ``g_k`` the distance to circle ``k`` (0 inside)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(circles) == 0:
        return np.ones(len(pts))
    g = np.maximum(circles.gaps(pts), 0.0)
    left: np.ndarray = np.maximum(1.0 - np.exp(-0.5 * (g / sigma) ** 2).sum(axis=1), 0.0)
    return left


class AdaptiveStrategy(MoveToCentroid):
    """Lloyd's method in the buffered Voronoi cell within the sensing disc, under the
    importance density less the repulsive fields of the obstacles within sensing range.

    Build it with the world's circles (it only uses those within its sensing radius):
    ``AdaptiveStrategy(context, AdaptiveParams(), Circles.from_world(spec), spec.bounds)``."""

    name: ClassVar[str] = "adaptive"
    Params: ClassVar[type] = AdaptiveParams
    params: AdaptiveParams

    def detected(self, p: np.ndarray) -> Circles:
        """The circles whose boundary lies within the sensing radius of ``p`` (2,) [m]."""
        if len(self.obstacles) == 0:
            return self.obstacles
        near = self.obstacles.gaps(p[None])[0] <= float(self.context.robot.sensor_radius)
        return self.obstacles.subset(near)

    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        p = obs.position
        dt = self.clock.elapsed(obs.time)
        sensor = float(self.context.robot.sensor_radius)
        near = [n.position for n in neighbours if np.hypot(*(n.position - p)) <= 2.0 * sensor]
        seen = self.detected(p)
        a, c, _ = buffered_voronoi(p, np.array(near).reshape(-1, 2), self.radius, self.bounds)
        da, dc = disc_halfplanes(p, sensor)
        polygon = halfplane_polygon(np.vstack([a, da]), np.concatenate([c, dc]), p)
        density = self.context.domain.mass_element.ravel()
        sigma = self.params.repulsion_sigma

        def weight(nodes: np.ndarray, xy: np.ndarray) -> np.ndarray:
            w: np.ndarray = density[nodes] * repulsive_weight(xy, seen, sigma)
            return w

        return self.decide(p, dt, polygon, weight, "lloyd", len(seen))
