"""What the baselines share: circular obstacles and Lloyd's move-to-centroid step in a convex
cell.

Both baselines are Lloyd-type methods (Cortes et al. 2004): each control period a robot builds a
convex cell, computes the centroid ``C`` of the cell under a density and moves towards it. As in
Wang et al.'s comparison, every method moves by Eq. 3 of that paper, ``u = -u_max (p - C) /
|p - C|``, integrated over the control period: the decision's goal is ``C`` itself and the trial
runner drives there at no more than ``u_max`` (see :func:`coverage_ros.bench.peak_trials.
run_trial`). A robot has converged when its speed falls below ``converged_speed`` (0.01 m/s in
Wang et al.): the unsaturated ``|C - p| / dt``, or its mean over the last two periods, ``|C -
p_prev| / (dt_prev + dt)``. The centroid is integrated over the raster cells whose centres lie in
the cell, so it is a step function of the robot's position; near a fixed point of Lloyd's
iteration the robot can then alternate between two points a fraction of a cell apart (a
two-cycle of 1 cm and 0.1 m/s on a 5 cm raster), whose mean is the fixed point - the discrete
form of having converged.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from coverage_ros.core.control.period import ControlPeriod
from coverage_ros.core.strategies.base import (
    Decision,
    Observation,
    SharedState,
    Strategy,
    StrategyContext,
    StrategyDetails,
)
from coverage_ros.core.strategies.bvc.cells import convex_polygon_cells, robot_halfplanes
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.errors import ConfigError

#: Fraction of the clearance kept as buffer when the full robot radius would leave the robot
#: outside its own cell (a robot already closer than its radius to an obstacle, a wall or
#: half-way to a neighbour; as in the ``bvc`` cells).
SHRUNK_BUFFER_FRACTION = 0.5


@dataclass(frozen=True)
class Circles:
    """Circular obstacles (discs)."""

    centers: np.ndarray  # (K, 2) [m]
    radii: np.ndarray  # (K,) [m] > 0

    def __post_init__(self) -> None:
        c = np.asarray(self.centers, dtype=np.float64).reshape(-1, 2)
        r = np.asarray(self.radii, dtype=np.float64).reshape(-1)
        if len(c) != len(r):
            raise ConfigError.at("circles", "need one radius per centre", (len(c), len(r)))
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(r)) and np.all(r > 0)):
            raise ConfigError.at("circles", "centres must be finite and radii finite and > 0",
                                 r.tolist())
        object.__setattr__(self, "centers", c)
        object.__setattr__(self, "radii", r)

    def __len__(self) -> int:
        return len(self.radii)

    @staticmethod
    def from_world(spec: WorldSpec) -> Circles:
        """The obstacles of a world made of circles only (others are refused: the baselines
        model obstacles as circles, and the world must be the one they model)."""
        if any(o.polygon is not None for o in spec.obstacles):
            raise ConfigError.at(f"world {spec.name!r}: obstacles", "must all be circles",
                                 sorted({o.kind for o in spec.obstacles}))
        return Circles(np.array([o.center for o in spec.obstacles]).reshape(-1, 2),
                       np.array([o.radius for o in spec.obstacles], dtype=np.float64))

    def gaps(self, points: np.ndarray) -> np.ndarray:
        """``(N, K)`` [m] signed distance from points to each circle's boundary (< 0 inside)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        d = np.hypot(pts[:, None, 0] - self.centers[None, :, 0],
                     pts[:, None, 1] - self.centers[None, :, 1])
        gaps: np.ndarray = d - self.radii[None, :]
        return gaps

    def subset(self, keep: np.ndarray) -> Circles:
        return Circles(self.centers[keep], self.radii[keep])


@dataclass(frozen=True)
class LloydParams:
    """Settings of a move-to-centroid baseline."""

    u_max: float | None = None  # [m/s] speed cap of Eq. 3 (None: the robot's v_max)
    period: float = 0.1  # [s] nominal control period (Wang et al.'s replanning interval)
    converged_speed: float = 0.01  # [m/s] converged when |C - p| / dt falls below this

    def __post_init__(self) -> None:
        for name in ("u_max", "period", "converged_speed"):
            value = getattr(self, name)
            if value is None and name == "u_max":
                continue
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not math.isfinite(value) or value <= 0:
                raise ConfigError.at(f"baseline.{name}", "must be a finite number > 0", value)


@dataclass(frozen=True)
class CentroidDetails(StrategyDetails):
    centroid: np.ndarray | None  # (2,) [m] C of the cell (None: the cell has no mass)
    speed: float  # [m/s] |C - p| / dt capped at u_max
    obstacles: int  # circles bounding (OAVC) or repelling (adaptive) in this update


def weighted_centroid(xy: np.ndarray, weight: np.ndarray) -> np.ndarray | None:
    """``(2,)`` [m] centroid of the sample points ``xy (N, 2)`` under ``weight (N,)`` (>= 0), or
    None when the weights sum to zero."""
    total = float(weight.sum())
    if not total > 0:
        return None
    centroid: np.ndarray = (xy * weight[:, None]).sum(axis=0) / total
    return centroid


def buffered_voronoi(center: np.ndarray, neighbours: np.ndarray, radius: float,
                     bounds: tuple[float, float, float, float], clearance: float = math.inf
                     ) -> tuple[np.ndarray, np.ndarray, float]:
    """The buffered Voronoi cell of a robot of ``radius`` [m] at ``center`` (2,) [m] among
    ``neighbours (J, 2)`` [m] in the walled arena ``bounds`` (xmin, ymin, xmax, ymax) [m], as
    half-planes ``(a (K, 2), c (K,))`` with ``a' x <= c`` inside: every bisector and wall
    pulled in by the buffer (Zhou et al. 2017). The buffer is ``radius``, or a share of the
    smallest clearance (to the walls, half-way to a neighbour, or ``clearance`` [m], e.g. to the
    obstacles) when that is smaller, so that the cell still holds the robot. Returns ``(a, c,
    buffer)``."""
    p = np.asarray(center, dtype=np.float64).reshape(2)
    nb = np.asarray(neighbours, dtype=np.float64).reshape(-1, 2)
    xmin, ymin, xmax, ymax = bounds
    clear = min(p[0] - xmin, xmax - p[0], p[1] - ymin, ymax - p[1], clearance)
    if len(nb):
        clear = min(clear, 0.5 * float(np.hypot(*(nb - p).T).min()))
    buffer = radius if clear > radius else SHRUNK_BUFFER_FRACTION * max(clear, 0.0)
    robots = robot_halfplanes(p, nb, buffer)
    walls = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])
    a = np.vstack([robots.a, walls])
    c = np.concatenate([robots.b - robots.beta, np.array([-xmin, xmax, -ymin, ymax]) - buffer])
    return a, c, buffer


class MoveToCentroid(Strategy):
    """Base of the baselines: the shared step of Lloyd's method in a convex cell. A subclass
    builds the cell polygon and the weight of its sample points; :meth:`decide` does the
    rest."""

    Params: ClassVar[type] = LloydParams
    params: LloydParams

    def __init__(self, context: StrategyContext, params: LloydParams | None,
                 obstacles: Circles,
                 bounds: tuple[float, float, float, float] | None = None) -> None:
        """``obstacles``: the circles the method knows of (it senses them globally or within
        its range; see the subclass); ``bounds``: the arena's walls ``(xmin, ymin, xmax,
        ymax)`` [m] (None: the map's extent)."""
        super().__init__(context, params)
        if not isinstance(obstacles, Circles):
            raise ConfigError.at(f"{self.name}: obstacles", "must be Circles",
                                 type(obstacles).__name__)
        self.obstacles = obstacles
        self.radius = float(context.robot.radius)
        self.u_max = float(self.params.u_max if self.params.u_max is not None
                           else context.robot.v_max)
        box = context.domain.geometry.extent() if bounds is None else bounds
        if not (len(box) == 4 and box[2] - box[0] > 2 * self.radius
                and box[3] - box[1] > 2 * self.radius):
            raise ConfigError.at(f"{self.name}: bounds", "must be (xmin, ymin, xmax, ymax) "
                                 "wider than the robot", box)
        xmin, ymin, xmax, ymax = (float(v) for v in box)
        self.bounds = (xmin, ymin, xmax, ymax)
        self.clock = ControlPeriod(self.params.period)
        self._last: tuple[np.ndarray, float] | None = None  # position and period, last update

    def shared_state(self, obs: Observation) -> SharedState:
        return SharedState(position=obs.position.copy(), weight=self.context.weight,
                           extra={"radius": self.radius})

    def decide(self, p: np.ndarray, dt: float, polygon: np.ndarray,
               weight_of: Callable[[np.ndarray, np.ndarray], np.ndarray], mode: str,
               obstacles: int) -> Decision:
        """The move-to-centroid decision in the convex ``polygon (M, 2)`` [m]: its samples are
        the domain nodes whose centre lies inside, weighted by ``weight_of(nodes, xy)``."""
        domain = self.context.domain
        if len(polygon) >= 3:
            rows, cols = convex_polygon_cells(domain.to_grid(polygon), domain.shape)
            nodes = rows * domain.shape[1] + cols
        else:
            nodes = np.zeros(0, np.int64)
        xy = domain.to_map(domain.node_centers(nodes))
        w = weight_of(nodes, xy) if len(nodes) else np.zeros(0)
        centroid = weighted_centroid(xy, w)
        target = p.copy() if centroid is None else centroid
        speed = min(self.u_max, float(np.hypot(*(target - p))) / dt)
        mean_speed = speed
        if self._last is not None:
            before, last_dt = self._last
            mean_speed = float(np.hypot(*(target - before))) / (last_dt + dt)
        self._last = (p.copy(), dt)
        mass = float(w.sum())
        d2 = ((xy - p) ** 2).sum(axis=1)
        return Decision(
            goal=target, target=target, velocity=None, cell=nodes[domain.free.ravel()[nodes]],
            shared=SharedState(position=p.copy(), weight=self.context.weight, mass=mass,
                               extra={"radius": self.radius}),
            converged=min(speed, mean_speed) < self.params.converged_speed,
            cost=float((d2 * w).sum()),
            mass=mass, mode=mode if centroid is not None else "stay",
            cell_polygon=polygon if len(polygon) >= 3 else None,
            details=CentroidDetails(centroid=centroid, speed=speed, obstacles=obstacles))
