"""Lee & Lee (IEEE Access 2024), adaptive CVT with agent dropout and reinsertion: the paper's
experiments (Sec. III-IV) side by side with its values.

Domains are 200 x 200 cells like the paper's (0.1 m cells: the 20 m arena of its real-time
section); the paper shows its targets and starts only as pictures, so they are re-drawn from
its text: two disjoint targets of a larger and a smaller area (a balanced split exists, as the
paper's Fig. 3 result shows one), agents "near the upper-left corner". The seed draws the start
cluster (:func:`corner_cluster`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from coverage_ros.bench.papers import Experiment, Metric
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies.acvt.dropout import AcvtConfig, AlphaCvt, DropoutConfig
from coverage_ros.core.world.density import TargetPolygons
from coverage_ros.core.world.grid import GridMap

PAPER = "Lee & Lee 2024"
RES = 0.1  # [m] per cell: 200 cells = the paper's 20 m arena
SIDE = 200  # [cells] the paper's 200 x 200 pixel domains (Sec. III)
TB3_RADIUS = 0.105  # [m] the TurtleBot3 of the paper's real-time section inflates the walls
#: Fig. 3 re-drawn: a 9 x 6 m and a 6 x 6 m target (the balanced split is 6 + 4 agents).
BIG = np.array([[10.0, 10.0], [19.0, 10.0], [19.0, 16.0], [10.0, 16.0]])
SMALL = np.array([[2.0, 1.5], [8.0, 1.5], [8.0, 7.5], [2.0, 7.5]])
#: [m] the start cluster's centre lies in this box of the upper-left corner (x0, y0, x1, y1).
UPPER_LEFT = (1.0, 16.5, 3.5, 19.0)
CLUSTER_SPREAD = 0.5  # [m] std of the agents about the cluster centre
CLUSTER_SEPARATION = 0.3  # [m] fewest distance between two agents of a start cluster


def corner_cluster(seed: int, k: int, box: tuple[float, float, float, float] = UPPER_LEFT,
                   arena: float = SIDE * RES) -> np.ndarray:
    """``(k, 2)`` [m]: a start cluster of ``k`` agents about a centre drawn in ``box``, the
    same for a seed whatever the method (so methods compare on equal starts)."""
    rng = np.random.default_rng(seed)
    x0, y0, x1, y1 = box
    centre = rng.uniform([x0, y0], [x1, y1])
    pts: list[np.ndarray] = []
    margin = 0.3  # [m] from the arena's edge
    while len(pts) < k:
        p = centre + rng.normal(0.0, CLUSTER_SPREAD * math.sqrt(max(k, 10) / 10), 2)
        if not (margin <= p[0] <= arena - margin and margin <= p[1] <= arena - margin):
            continue
        if all(math.hypot(*(p - q)) >= CLUSTER_SEPARATION for q in pts):
            pts.append(p)
    return np.array(pts)


@functools.lru_cache(maxsize=8)
def two_targets() -> CoverageDomain:
    """Fig. 3 re-drawn: the two disjoint targets in the open 20 m arena."""
    grid = GridMap(np.zeros((SIDE, SIDE), np.int8), RES)
    return CoverageDomain.from_grid(grid, TB3_RADIUS, TargetPolygons((BIG, SMALL)))


def _solvers(domain: CoverageDomain) -> dict[str, AlphaCvt]:
    return {
        "iCVT": AlphaCvt(domain, AcvtConfig(dropout=DropoutConfig(enabled=False),
                                            projection=False)),
        "iCVT+Projection": AlphaCvt(domain, AcvtConfig(dropout=DropoutConfig(enabled=False))),
        "alpha-CVT": AlphaCvt(domain),
    }


def fig3(seed: int) -> dict[str, float]:
    """Fig. 3: 10 agents from the upper-left corner, two disjoint targets."""
    starts = corner_cluster(seed, 10)
    return {f"I, {name}": solver.run(starts).metric[-1]
            for name, solver in _solvers(two_targets()).items()}


def experiments() -> list[Experiment]:
    return [
        Experiment(PAPER, "Fig. 3", "two disjoint targets, 10 agents from the upper-left corner",
                   (Metric("I, iCVT", 1.2),
                    Metric("I, iCVT+Projection", 0.44),
                    Metric("I, alpha-CVT", 0.046)),
                   fig3, redrawn=True, key="lee2024/fig3"),
    ]
