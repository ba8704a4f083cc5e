"""The methods Wang et al. (2024, Table I) compare their ``bvc`` against, as far as their
published descriptions allow (see each module's docstring for what is and is not known).

They implement the :class:`~coverage_ros.core.strategies.base.Strategy` interface so the trial
harness (:func:`coverage_ros.bench.peak_trials.run_trial`, through a strategy factory) can run
them, but they are **not** in the strategy registry: the live team's strategies stay the five
of :mod:`coverage_ros.core.strategies`.

* :mod:`.oavc` - obstacle-aware Voronoi cells, tangent lines to circular obstacles, global
  sensing (Abdulghafoor & Bakolas 2021);
* :mod:`.adaptive` - a repulsive density around detected obstacles, local sensing (Bai, Wang,
  Xiong, Svinin & Magid 2022);
* :mod:`.common` - circular obstacles and the move-to-centroid step they share.

Obstacles are circles, as in Wang et al.'s comparison ("the obstacles are modeled as the same
shape in [11]"); points are ``(N, 2) float64`` [m] in the map frame.
"""

from coverage_ros.core.baselines.adaptive import AdaptiveParams, AdaptiveStrategy
from coverage_ros.core.baselines.common import Circles, LloydParams
from coverage_ros.core.baselines.oavc import OavcStrategy

__all__ = ["AdaptiveParams", "AdaptiveStrategy", "Circles", "LloydParams", "OavcStrategy"]
