"""Breitenmoser et al. (2010) settings re-drawn from the paper's text: the robots (TurtleBot3s,
the e-pucks of Sec. VI and the ideal simulation's near-point robot), the worlds of Figs. 2b-5
and the starts the seed draws (:func:`start_cluster`, :func:`fig2b_start`).

The paper gives its settings only as pictures without coordinates. Our robots are discs with a
lidar, not the paper's point robots with infinite sensing; TangentBug keeps ``radius +
follow_margin`` from the walls, so the projection p* of a virtual target t is the point of that
clearance contour closest to t (:func:`clearance_projection`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np
from scipy import ndimage

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.world import LidarSpec, RobotSpec, parse_world
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.errors import ConfigError

#: A TurtleBot3 whose lidar has 120 beams (3 degrees: a wall 3.5 m away returns every 18 cm,
#: closer than the 0.41 m clearance disc; a third of the LDS-01's beams keeps runs fast).
ROBOT = RobotSpec(lidar=LidarSpec(beams=120))
N_ROBOTS = 5  # the paper's teams (Figs. 3-5)
#: [m] (x0, y0, x1, y1): the start cluster's centre is drawn in this box of the bottom-left
#: corner, where the robots of the shipped U world start (Figs. 3-5 start the robots together).
CORNER = (0.6, 0.6, 1.2, 1.2)
CLUSTER_SPREAD = 0.25  # [m] std of the robots about the cluster's centre
CLUSTER_SEPARATION = 0.3  # [m] fewest distance between two robots of a cluster
#: The re-drawn worlds: (bounds [m], obstacles, density, grid cell [m]). Fig. 3 is the shipped
#: U world (config/worlds/u_shape.yaml); Fig. 4 a room with two free-standing blocks; Fig. 2b
#: a U opening to the right (a bar from the right wall) under a density rising toward the
#: branches' ends, so that the Euclidean centroid lies in the bar; Fig. 5 the 1 m x 1 m
#: e-puck arena with a U like Fig. 3's.
WORLDS = {
    "fig3": ([0.0, 0.0, 10.0, 8.0], [{"type": "box", "center": [5.0, 5.25], "size": [3.0, 5.5]}],
             None, 0.05),
    "fig4": ([0.0, 0.0, 10.0, 8.0], [{"type": "box", "center": [5.0, 4.0], "size": [2.0, 2.0]},
                                     {"type": "box", "center": [8.0, 2.0], "size": [1.5, 1.5]}],
             None, 0.05),
    "fig2b": ([0.0, 0.0, 6.0, 4.0], [{"type": "box", "center": [4.0, 1.95], "size": [4.0, 0.9]}],
              {"type": "gaussian_mixture", "floor": 0.2,
               "components": [{"mean": [6.0, 2.2], "sigma": 2.0}]}, 0.05),
    "fig5": ([0.0, 0.0, 1.0, 1.0], [{"type": "box", "center": [0.5, 0.65], "size": [0.3, 0.7]}],
             None, 0.01),
}
#: Fig. 2b: one robot starts in the U's base (x0, y0, x1, y1 [m]).
BASE = (0.4, 0.4, 1.4, 3.6)
#: Fig. 5 (Sec. VI): the e-puck - 7 cm across (paper); 1000 steps/s of its steppers on 41 mm
#: wheels = 0.128 m/s; turning rate 2 v / 53 mm axle. Infinite sensing emulated by a lidar
#: reaching across the arena.
EPUCK = RobotSpec(radius=0.035, v_max=0.128, w_max=4.8,
                  lidar=LidarSpec(beams=120, range_min=0.005, range_max=1.5))
#: The paper's ideal simulation: as near a point robot as TangentBug's brake allows (its
#: clearance must exceed the radius + 0.02 m safety margin).
POINT = replace(EPUCK, radius=0.005)
#: TangentBug scaled to the e-puck (defaults over the TurtleBot3 radius, times 0.035 / 0.105).
EPUCK_BUG = {"follow_margin": 0.035, "lookahead": 0.07, "loop_tolerance": 0.05,
             "leave_margin": 0.035}
POINT_BUG = {**EPUCK_BUG, "follow_margin": 0.025}
EPUCK_CORNER = (0.08, 0.08, 0.14, 0.14)  # [m] cluster centre box in the arena's corner
EPUCK_SPREAD, EPUCK_SEPARATION = 0.04, 0.08  # [m] an e-puck diameter + 1 cm apart


@functools.lru_cache(maxsize=8)
def world(name: str, radius: float = ROBOT.radius) -> tuple[WorldSpec, CoverageDomain]:
    """A re-drawn world of :data:`WORLDS` (uniform density unless given, as the paper's
    simulations) and its domain for a disc robot of ``radius`` [m]."""
    bounds, obstacles, density, res = WORLDS[name]
    data = {"name": name, "resolution": res, "bounds": bounds, "obstacles": obstacles}
    if density is not None:
        data["density"] = density
    spec = parse_world(data)
    return spec, CoverageDomain.from_grid(spec.grid, radius, spec.density)


def start_cluster(seed: int, domain: CoverageDomain, k: int = N_ROBOTS,
                  box: tuple[float, float, float, float] = CORNER,
                  spread: float = CLUSTER_SPREAD,
                  separation: float = CLUSTER_SEPARATION) -> np.ndarray:
    """``(k, 3)`` start poses ``(x [m], y [m], yaw [rad])``: a cluster about a centre drawn in
    ``box``, every robot on a free point and ``separation`` [m] from the others."""
    rng = np.random.default_rng(seed)
    centre = rng.uniform(box[:2], box[2:])
    pts: list[np.ndarray] = []
    for _ in range(10_000):
        p = centre + rng.normal(0.0, spread, 2)
        if domain.is_free_point(p) and all(math.hypot(*(p - q)) >= separation for q in pts):
            pts.append(p)
            if len(pts) == k:
                return np.column_stack([np.array(pts), rng.uniform(-math.pi, math.pi, k)])
    raise ConfigError.at("start_cluster", f"no {k} separated free starts near", centre.tolist())


def clearance_projection(spec: WorldSpec, target: np.ndarray, clearance: float,
                         upsample: int = 5) -> np.ndarray:
    """``(2,)`` [m]: the point at least ``clearance`` [m] from every obstacle cell (and the
    map's edge) closest to ``target (2,)`` - the projection p* for a robot that keeps that
    clearance (distance transform on the grid refined ``upsample`` times)."""
    grid = spec.grid
    occ = np.kron(grid.occupied_mask(), np.ones((upsample, upsample), dtype=bool))
    occ = np.pad(occ, 1, constant_values=True)
    dist = ndimage.distance_transform_edt(~occ)[1:-1, 1:-1] * (grid.resolution / upsample)
    rows, cols = np.nonzero(dist >= clearance)
    xy = grid.grid_to_world(np.stack([(cols + 0.5) / upsample, (rows + 0.5) / upsample], -1))
    return xy[int(np.argmin(np.hypot(*(xy - target).T)))]


def centroid(domain: CoverageDomain) -> np.ndarray:
    """``(2,)`` [m]: the mass centroid of the whole free space (one robot's Euclidean target)."""
    w = domain.mass_element.ravel()
    X, Y = domain.geometry.all_cell_centers()
    return np.stack([X.ravel(), Y.ravel()], axis=-1).T @ w / w.sum()



def fig2b_start(seed: int, k: int) -> np.ndarray:
    """``(1, 3)``: start ``k`` of ``seed`` in the base of the Fig. 2b U."""
    rng = np.random.default_rng([seed, k])
    return np.array([[*rng.uniform(BASE[:2], BASE[2:]), rng.uniform(-math.pi, math.pi)]])
