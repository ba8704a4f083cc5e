"""Coordinated exploration of an unknown map: geodesic power Voronoi cells on the belief's
entropy-weighted metric, the generalized Lloyd control, and the greedy mode (Bhattacharya et al.
2014, Sec. 4.2).

Every update the robot builds, from its belief (:class:`~coverage_ros.core.exploration.belief.
BeliefSnapshot`), the coverage domain of Eq. 9 (:func:`~coverage_ros.core.exploration.maps.
entropy_domain`): density w and isotropic metric zeta I equal to the entropy where it is at least
tau, and small constants where the map is explored. It computes its own cell among its
neighbours and the Eq. 8 control, whose goal is the cell's virtual centroid - pulled toward the
unexplored parts of the cell, which the metric stretches out, so that the team splits the unknown
among its members.

When that control vanishes (the goal is closer than ``stall_distance``) while the cell still holds
unexplored mass (the integral of w over the cell exceeds that of eps_w), the robot switches to
the *greedy* mode: it heads for the closest vertex whose entropy is above tau (closest along the
metric's shortest paths from the robot) until that vertex is explored or reached, then returns
to the Lloyd mode. Once no reachable vertex is above tau, w and zeta stop changing and the team
converges to the coverage of the explored map, as in the paper.

A target that cannot be explored (a cell hidden under another robot, or inside furniture whose
outline the lidar has not closed yet) would hold a robot for ever; one the robot has stayed
within ``give_up_radius`` of for ``give_up_after`` seconds while it stayed unexplored is given up
(the blacklist of explore_lite's frontiers). What is banned then is the target's *pocket* - the
connected unexplored vertices around it - when the pocket is at most ``ban_pocket_area``: the
inside of a table whose outline has a gap is one such pocket, and banning it a ``ban_radius``
disc at a time would hold a whole team at the table for minutes. A larger pocket (a real
frontier into the unknown) loses only the vertices within ``ban_radius`` of the target.
Targets in one pocket count as one while the robot stays near it.
Banned vertices are never targets again, and while unexplored they are occupied in this
robot's coverage domain: its cell and Lloyd goal leave the given-up inside of a table out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy import ndimage
from scipy.sparse.csgraph import connected_components, dijkstra

from coverage_ros.core.exploration.belief import BeliefSnapshot
from coverage_ros.core.exploration.maps import EntropyMetric, entropy_domain
from coverage_ros.core.geodesic.cell import CellResult, geodesic_cell
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tessellation import METHODS, Generator
from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    SharedState,
    Strategy,
    StrategyContext,
    StrategyDetails,
)
from coverage_ros.errors import ConfigError

#: Relative margin on "the integral of w over the cell exceeds that of eps_w" (round-off).
MASS_MARGIN = 1e-6
#: The paper's control (``paper``), and ours (``nearest``).
VARIANTS = ("paper", "nearest")


@dataclass(frozen=True)
class ExploreParams:
    """Settings of the exploring ``geodesic`` strategy."""

    tau: float = 0.55  # [nats] vertices at or above this entropy are unexplored (Eq. 9)
    eps_w: float = 0.01  # density of explored vertices (Eq. 9)
    eps_zeta: float = 0.1  # metric weight of explored vertices (Eq. 9)
    stall_distance: float = 0.15  # [m] a Lloyd goal closer than this = the control vanished
    method: str = "auto"  # sources and tangents (auto: lookahead on this curved metric)
    variant: str = "nearest"  # "nearest" or "paper" (Lloyd + greedy; see module docstring)
    give_up_after: float = 20.0  # [s] near an unexplorable target this long: give it up
    give_up_radius: float = 1.5  # [m] "near" for give_up_after
    ban_radius: float = 0.3  # [m] unexplored vertices this close to a given-up target
    ban_pocket_area: float = 4.0  # [m^2] a given-up target's whole pocket up to this area

    def __post_init__(self) -> None:
        self.metric()  # validates tau, eps_w, eps_zeta
        if self.variant not in VARIANTS:
            raise ConfigError.at("variant", "unknown variant", self.variant,
                                 f"one of {VARIANTS}")
        if not (math.isfinite(self.stall_distance) and self.stall_distance > 0):
            raise ConfigError.at("stall_distance", "must be a number > 0 [m]",
                                 self.stall_distance)
        for name in ("give_up_after", "give_up_radius", "ban_radius", "ban_pocket_area"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError.at(name, "must be a number > 0", v)
        if self.method not in METHODS:
            raise ConfigError.at("method", "unknown method", self.method, f"one of {METHODS}")

    def metric(self) -> EntropyMetric:
        return EntropyMetric(self.tau, self.eps_w, self.eps_zeta)


@dataclass(frozen=True)
class ExploreDetails(StrategyDetails):
    lloyd_goal: np.ndarray  # (2,) [m] the Eq. 8 goal (virtual centroid, reachable part)
    greedy_target: np.ndarray | None  # (2,) [m] the greedy mode's vertex, if greedy
    unexplored_mass: float  # integral over the own cell of (w - eps_w)
    unexplored_cells: int  # own cell's vertices at or above tau


class ExploreStrategy(Strategy):
    """See module docstring."""

    name: ClassVar[str] = "geodesic"
    Params: ClassVar[type] = ExploreParams
    params: ExploreParams
    explores: ClassVar[bool] = True

    def __init__(self, context: StrategyContext, params: ExploreParams | None = None) -> None:
        super().__init__(context, params)
        self.metric = self.params.metric()
        self.target: np.ndarray | None = None  # greedy target (2,) [m], None in Lloyd mode
        self.banned: np.ndarray | None = None  # (H, W) bool: given-up vertices (see docstring)
        self.given_up: list[np.ndarray] = []  # the given-up targets (2,) [m]
        self.given_up_cells: list[tuple[int, bool]] = []  # (vertices banned, a whole pocket)
        self._near: tuple[np.ndarray, float] | None = None  # (target, since [s]) when near it
        self._pocket: np.ndarray | None = None  # (H, W) bool: the near target's small pocket
        #: (entropy domain, bans, that domain with the banned unexplored vertices occupied)
        self._without_banned: tuple[CoverageDomain, int, CoverageDomain] | None = None

    def shared_state(self, obs: Observation) -> SharedState:
        return SharedState(position=obs.position.copy(), weight=self.context.weight,
                           extra={"greedy": 0.0})

    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        if obs.belief is None:
            raise ConfigError.at("geodesic (explore)", "needs the robot's belief of the map")
        p = obs.position
        domain, e = self._domain(obs.belief)
        own = Generator(p, self.context.weight)
        others = [Generator(n.position, n.state.weight) for n in neighbours]
        cell = geodesic_cell(domain, own, others, method=self.params.method, whole=True)
        area = domain.graph.cell_area().ravel()[cell.nodes]
        unexplored = float((domain.mass_element.ravel()[cell.nodes]
                            - self.metric.eps_w * area).sum())
        unexplored_cells = int((e.ravel()[cell.nodes] >= self.metric.tau).sum())
        lloyd_step = float(np.hypot(*(cell.goal - p)))
        if self.banned is not None:
            e = np.where(self.banned, 0.0, e)  # given-up vertices count as explored for targets
        if self.target is not None and not self._still_greedy(domain, e, p):
            self.target = None
        mode = self._choose(domain, e, p, cell, lloyd_step, unexplored, area)
        if self._give_up(domain, e, p, obs.time):
            assert self.banned is not None  # (a target given up is banned)
            e = np.where(self.banned, 0.0, e)
            mode = self._choose(domain, e, p, cell, lloyd_step, unexplored, area)
        target = self.target
        greedy = target is not None
        goal = target.copy() if target is not None else cell.goal
        converged = not greedy and lloyd_step < self.context.convergence_tolerance
        return Decision(
            goal=goal, velocity=None, cell=cell.nodes,
            shared=SharedState(position=p.copy(), weight=self.context.weight, mass=cell.mass,
                               extra={"greedy": float(greedy)}),
            converged=converged, cost=cell.cost, mass=cell.mass, mode=mode,
            details=ExploreDetails(lloyd_goal=cell.goal, greedy_target=None if target is None
                                   else target.copy(), unexplored_mass=unexplored,
                                   unexplored_cells=unexplored_cells))

    def _choose(self, domain: CoverageDomain, e: np.ndarray, p: np.ndarray, cell: CellResult,
                lloyd_step: float, unexplored: float, area: np.ndarray) -> str:
        """Keeps or picks ``self.target`` by the variant's rule; returns the mode."""
        if self.params.variant == "nearest":
            return self._nearest(domain, e, p, cell.nodes, cell.distances)
        if (self.target is None and lloyd_step < self.params.stall_distance
                and unexplored > MASS_MARGIN * max(float(area.sum()), 1e-12)):
            self.target = closest_unexplored(domain, e, p, self.metric.tau)
        return "greedy" if self.target is not None else "lloyd"

    def _domain(self, belief: BeliefSnapshot) -> tuple[CoverageDomain, np.ndarray]:
        """The belief's entropy domain, with this robot's banned unexplored vertices taken as
        occupied (memoized per belief snapshot and ban)."""
        radius, connectivity = self.context.robot.radius, len(self.context.domain.graph.offsets)
        domain, e = entropy_domain(belief, radius, self.metric, connectivity)
        if self.banned is None or not (self.banned & (e >= self.metric.tau)).any():
            return domain, e
        memo = self._without_banned
        if memo is None or memo[0] is not domain or memo[1] != len(self.given_up):
            banned = entropy_domain(belief, radius, self.metric, connectivity,
                                    blocked=self.banned & (e >= self.metric.tau))[0]
            memo = self._without_banned = (domain, len(self.given_up), banned)
        return memo[2], e

    def _give_up(self, domain: CoverageDomain, e: np.ndarray, p: np.ndarray, now: float
                 ) -> bool:
        """Whether the target was just given up (see module docstring); bans its pocket, or
        around it."""
        t = self.target
        if t is None or not float(np.hypot(*(t - p))) <= self.params.give_up_radius:
            self._near, self._pocket = None, None
            return False
        # A target within ban_radius of where it was, or in the same small pocket, is the same.
        held = self._near
        same = held is not None and (
            np.hypot(*(held[0] - t)) <= self.params.ban_radius
            or (self._pocket is not None and self._pocket[self._cell(domain, t)]))
        if held is None or not same:
            self._near, self._pocket = (t.copy(), now), self.pocket(domain, e, t)
            return False
        if now - held[1] < self.params.give_up_after:
            return False
        if self.banned is None:
            self.banned = np.zeros(domain.shape, bool)
        before = int(self.banned.sum())
        pocket = self.pocket(domain, e, t)
        if pocket is not None:
            self.banned |= pocket
        else:
            centres = domain.to_map(domain.node_centers(np.arange(self.banned.size)))
            for point in (held[0], t):
                close = np.hypot(*(centres - point).T) <= self.params.ban_radius
                self.banned |= close.reshape(domain.shape)
        self.given_up.append(t.copy())
        self.given_up_cells.append((int(self.banned.sum()) - before, pocket is not None))
        self.target, self._near, self._pocket = None, None, None
        return True

    def describe(self) -> list[str]:
        if not self.given_up:
            return []
        what = ", ".join(f"({t[0]:.2f}, {t[1]:.2f}): {n} vertices" + (" (its pocket)" if whole
                                                                       else "")
                         for t, (n, whole) in zip(self.given_up, self.given_up_cells,
                                                  strict=True))
        return [f"gave up {len(self.given_up)} exploration target(s) that stayed unexplored "
                f"{self.params.give_up_after:g} s within {self.params.give_up_radius:g} m: "
                f"{what}"]

    def pocket(self, domain: CoverageDomain, e: np.ndarray, point: np.ndarray
               ) -> np.ndarray | None:
        """``(H, W) bool``: the unexplored vertices connected (8-neighbours) to ``point``'s,
        if they cover at most ``ban_pocket_area``; None for a larger pocket or an explored
        point."""
        unexplored = e >= self.metric.tau
        cell = self._cell(domain, point)
        if not unexplored[cell]:
            return None
        labels, _ = ndimage.label(unexplored, structure=np.ones((3, 3), bool))
        mine: np.ndarray = labels == labels[cell]
        if mine.sum() * domain.resolution ** 2 > self.params.ban_pocket_area:
            return None
        return mine

    @staticmethod
    def _cell(domain: CoverageDomain, point: np.ndarray) -> tuple[int, int]:
        r, c = domain.geometry.world_to_cell(np.asarray(point, np.float64)[None])[0]
        H, W = domain.shape
        return min(max(int(r), 0), H - 1), min(max(int(c), 0), W - 1)

    def _nearest(self, domain: CoverageDomain, e: np.ndarray, p: np.ndarray, nodes: np.ndarray,
                 distances: np.ndarray) -> str:
        """The ``nearest`` variant: the target is the own cell's unexplored vertex nearest along
        the metric (kept while it stays unexplored, unreached and in the cell); a robot whose
        cell is explored heads for the nearest unexplored vertex anywhere. Returns the mode."""
        if self.target is not None and self._in(domain, self.target, nodes):
            return "frontier"
        open_ = e.ravel()[nodes] >= self.metric.tau
        if open_.any():
            k = int(np.argmin(np.where(open_, distances, np.inf)))
            self.target = domain.to_map(domain.node_centers(nodes[k:k + 1]))[0]
            return "frontier"
        self.target = closest_unexplored(domain, e, p, self.metric.tau)
        return "lloyd" if self.target is None else "greedy"

    @staticmethod
    def _in(domain: CoverageDomain, point: np.ndarray, nodes: np.ndarray) -> bool:
        cell = domain.geometry.world_to_cell(point[None])[0]
        return bool(np.isin(cell[0] * domain.shape[1] + cell[1], nodes))

    def _still_greedy(self, domain: CoverageDomain, e: np.ndarray, p: np.ndarray) -> bool:
        """The greedy target is kept until it is explored or reached."""
        assert self.target is not None
        cell = domain.geometry.world_to_cell(self.target[None])[0]
        if not domain.geometry.contains_cell(cell[None])[0]:
            return False
        reached = float(np.hypot(*(self.target - p))) < self.params.stall_distance
        return bool(e[cell[0], cell[1]] >= self.metric.tau) and not reached and \
            reachable(domain, p, self.target)


def reachable(domain: CoverageDomain, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether ``b`` can be reached from ``a`` (map frame) on the domain's graph (an unknown
    pocket inside an obstacle is not, once the obstacle's outline has been seen)."""
    key = "components"
    if key not in domain._cache:
        domain._cache[key] = connected_components(domain.graph.csr, directed=False)[1]
    labels = domain._cache[key]
    cell = domain.geometry.world_to_cell(np.asarray(b, dtype=np.float64)[None])[0]
    if not domain.geometry.contains_cell(cell[None])[0] or not domain.free[cell[0], cell[1]]:
        return False
    na = domain.snap(a)[0]
    return len(na) > 0 and bool(labels[na[0]] == labels[cell[0] * domain.shape[1] + cell[1]])


def closest_unexplored(domain: CoverageDomain, e: np.ndarray, p: np.ndarray,
                       tau: float) -> np.ndarray | None:
    """(2,) [m] the accessible vertex of entropy >= ``tau`` closest to ``p`` along the domain's
    metric, or None if none can be reached."""
    unexplored = (e >= tau) & domain.free
    if not unexplored.any():
        return None
    nodes, _, grid = domain.snap(p)
    if len(nodes) == 0:
        return None
    # The cells around the robot are a fraction of a cell away: their offsets do not matter.
    # Searched out to a limit, doubled until an unexplored vertex lies within it: distances
    # within the limit are exact, so its nearest is the whole search's. The first limit is
    # twice the least a path to the nearest unexplored vertex can be (its straight line times
    # the metric's lower bound; on a chart that wraps, the whole map at once).
    rows, cols = np.nonzero(unexplored)
    cells = float(np.hypot(cols + 0.5 - grid[0], rows + 0.5 - grid[1]).min())
    edge = domain.graph.max_edge_cost
    limit = math.inf if any(domain.graph.wrap) else \
        max(2.0 * cells * domain.resolution * domain.metric_lower_bound, 4.0 * edge)
    while True:
        d = dijkstra(domain.graph.csr, directed=True, indices=nodes, min_only=True,
                     limit=limit)
        best = np.where(unexplored.ravel(), d, np.inf)
        k = int(np.argmin(best))
        if np.isfinite(best[k]):
            break
        if not float(d[np.isfinite(d)].max(initial=0.0)) >= limit - edge:  # (inf: never)
            return None  # (no path reaches the limit: all that can be reached was)
        limit *= 2.0
    point: np.ndarray = domain.to_map(domain.node_centers(np.array([k])))[0]
    return point
