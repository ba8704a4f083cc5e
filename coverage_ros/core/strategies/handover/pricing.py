"""What one robot of the closet escape computes to price moves (:mod:`.protocol`): its own
split offers, and the bounds and descents of a move into a neighbour's cell, each kept until
some generator it hears moves by a grid cell (a settled team prices the same configuration
update after update)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from coverage_ros.core.geodesic.cell import CellResult
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies.base import Neighbour
from coverage_ros.core.strategies.handover.bounds import (
    Known,
    Tessellations,
    descent_change,
    joint_change,
    known_cells,
    removal_increase,
)
from coverage_ros.core.strategies.handover.published import Offer
from coverage_ros.core.strategies.handover.settings import HandoverSettings
from coverage_ros.core.strategies.handover.split import SplitOffer, room_offers, split_offers

#: Power weights closer than this [m] count as equal (the bounds assume equal weights).
WEIGHT_MATCH = 1e-9
#: Starts a move's descent is priced from (:meth:`Prices.descent`): the configuration heard and
#: others shifted from it by at most :data:`JITTER`. A descent through a doorway can go either
#: way from starts a few cm apart (the robot that follows into the vacated cell, or the one
#: that stays), live positions are known only that well, and a move is backed by a
#: configuration next to it (:mod:`.bounds`): one reached from any of the starts.
DESCENT_DRAWS = 5
#: Largest shift [grid cells] of each generator, per axis, in the other starts of a descent.
JITTER = 0.5
#: A price's key: (target robot id, its point x, y [m], rings: -1 H heard, 0 the descent
#: (the least of its starts), -2 the descent paying from every start,
#: >= 1 the joint bound, the saving [units of H] past which the descent stops)
Memo = tuple[int, float, float, int, float]


@dataclass
class Prices:
    """One robot's prices of the configuration it last saw (module docstring)."""

    domain: CoverageDomain
    method: str
    steps: int  # Lloyd steps of the split and of the removal
    joint_steps: int  # Lloyd steps of the joint bound
    room_starts: int  # starts of :func:`.split.room_offers` over a neighbour's cell
    #: [m] longest step of a robot along the descents (0: whole Lloyd steps;
    #: :func:`.bounds.descent_change`)
    descent_step: float = 0.0
    _offer: tuple[np.ndarray, list[SplitOffer]] | None = field(default=None, repr=False)
    _removal: tuple[np.ndarray, dict[int, float], Tessellations] | None = field(
        default=None, repr=False)
    _joint: tuple[np.ndarray, Known, dict[Memo, float]] | None = field(
        default=None, repr=False)
    #: room offers (:func:`.split.room_offers`) per robot id, of the configuration of ``_joint``
    _rooms: dict[int, list[Offer]] = field(default_factory=dict, repr=False)
    #: the cells of the shifted starts of the descents (:data:`DESCENT_DRAWS`), by draw
    _shifted: dict[int, Known] = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, domain: CoverageDomain, method: str, settings: HandoverSettings) -> Prices:
        """A robot's prices under the handover's ``settings``."""
        s = settings
        return cls(domain, method, s.steps, s.joint_steps, s.descent_rooms, s.descent_step)

    def offers(self, key: np.ndarray, cell: CellResult, weight: float
               ) -> list[SplitOffer]:
        """The own split offers, computed again only when some generator moved by a cell."""
        if self._offer is None or not same_config(self._offer[0], key, self.domain.resolution):
            offers = split_offers(self.domain, cell.nodes, cell.distances, cell.cost, weight,
                                  cell.cell_radius, self.steps, self.method)
            self._offer = (key, offers)
        return self._offer[1]

    def known(self, key: np.ndarray, position: np.ndarray, neighbours: Sequence[Neighbour]
              ) -> tuple[Known, dict[Memo, float]]:
        """The cells of all it hears and the prices found on them (again once one moved)."""
        if self._joint is None or not same_config(self._joint[0], key, self.domain.resolution):
            gens = np.vstack([position[None], [n.position for n in neighbours]])
            self._joint = (key, known_cells(self.domain, gens, self.method), {})
            self._rooms, self._shifted = {}, {}
        return self._joint[1], self._joint[2]

    def heard_cost(self, key: np.ndarray, position: np.ndarray,
                   neighbours: Sequence[Neighbour], weight: float) -> float:
        """H of the cells of all it hears and its own (equal power weights ``weight``): the
        sum over every node they reach of (g^2 - weight^2) w dA."""
        known, values = self.known(key, position, neighbours)
        memo = (-1, 0.0, 0.0, -1, 0.0)  # (rings -1: not a price)
        if memo not in values:
            d = known.distances
            reached = np.isfinite(d)
            wdA = self.domain.mass_element.ravel()
            values[memo] = float(((d[reached] ** 2 - weight ** 2) * wdA[reached]).sum())
        return values[memo]

    def rooms(self, key: np.ndarray, position: np.ndarray, weight: float,
              neighbours: Sequence[Neighbour], target: int, offers: Sequence[Offer]
              ) -> list[Offer]:
        """Points in the rooms of ``target``'s cell (of the tessellation of all it hears)
        other than those of its own ``offers``' points (:func:`.split.room_offers`)."""
        known, _ = self.known(key, position, neighbours)
        if target not in self._rooms:
            k = 1 + [n.robot_id for n in neighbours].index(target)
            nodes = np.flatnonzero(known.labels == k)
            g = known.distances[nodes]
            theirs = [o for o in offers if o.robot_id == target]
            base = theirs[0].base if theirs else 0.0
            taken = np.array([o.point for o in theirs]).reshape(-1, 2)
            rooms = room_offers(self.domain, nodes, g, base, weight,
                                float(g.max(initial=0.0)), self.steps,
                                self.room_starts, taken, self.method)
            self._rooms[target] = [Offer((target, 2 + r), o.gain, o.point, o.base)
                                   for r, o in enumerate(rooms)]
        return self._rooms[target]

    def joint(self, key: np.ndarray, position: np.ndarray, weight: float,
              neighbours: Sequence[Neighbour], target: Offer, rings: int) -> float:
        """The bound of :func:`.bounds.joint_change` for a move into ``target``'s cell at its
        offered point with ``rings`` (>= 1) of cells re-spreading."""
        if any(abs(n.state.weight - weight) >= WEIGHT_MATCH for n in neighbours):
            return math.inf  # the bound assumes equal power weights
        known, values = self.known(key, position, neighbours)
        point = target.point
        memo = (target.robot_id, float(point[0]), float(point[1]), rings, 0.0)
        if memo not in values:
            t = 1 + [n.robot_id for n in neighbours].index(target.robot_id)
            values[memo] = joint_change(self.domain, known, weight, t, point,
                                        self.joint_steps, self.method, rings,
                                        self.descent_step).increase
        return values[memo]

    def descent(self, key: np.ndarray, position: np.ndarray, weight: float,
                neighbours: Sequence[Neighbour], target: Offer,
                enough: float, every: bool = False) -> float:
        """:func:`.bounds.descent_change` of a move to ``target``'s offered point, every
        generator it hears descending, stopped once H is lower by more than ``enough``: the
        least over the configuration heard and up to ``DESCENT_DRAWS - 1`` others shifted by
        at most :data:`JITTER`, drawn until one pays more than ``enough``; with ``every``, the
        largest over all ``DESCENT_DRAWS`` starts, drawn until one does not pay (a move that
        pays from each of them, not only from the most favourable)."""
        if any(abs(n.state.weight - weight) >= WEIGHT_MATCH for n in neighbours):
            return math.inf  # the descent prices equal power weights
        known, values = self.known(key, position, neighbours)
        point = target.point
        # (rings 0 / -2: the descent, with where it stops)
        memo = (target.robot_id, float(point[0]), float(point[1]), -2 if every else 0,
                float(enough))
        if memo not in values:
            movers = list(range(1, len(known.generators)))
            found = -math.inf if every else math.inf
            for draw in range(DESCENT_DRAWS):
                start = known if draw == 0 else self.shifted(known, draw)
                increase = descent_change(self.domain, start, weight, movers, point,
                                          self.method, enough=enough,
                                          max_step=self.descent_step).increase
                found = max(found, increase) if every else min(found, increase)
                if (found < -enough) != every:
                    break
            values[memo] = found
        return values[memo]

    def shifted(self, known: Known, draw: int) -> Known:
        """The cells of ``known``'s generators each shifted by a fixed draw of at most
        :data:`JITTER` grid cells per axis (kept where the shift leaves free space)."""
        if draw not in self._shifted:
            gens = known.generators
            shift = np.random.default_rng(draw).uniform(-1.0, 1.0, gens.shape) \
                * JITTER * self.domain.resolution
            moved = gens + shift
            free = np.array([self.domain.is_free_point(q) for q in moved])
            self._shifted[draw] = known_cells(
                self.domain, np.where(free[:, None], moved, gens), self.method)
        return self._shifted[draw]

    def removal(self, key: np.ndarray, position: np.ndarray, weight: float,
                cell: CellResult, neighbours: Sequence[Neighbour],
                bordering: Sequence[int], target: int) -> float:
        """The own removal bound with ``target`` held fixed if it borders the own cell (one
        bound for all other targets), computed again only when some generator moved by a
        cell."""
        if self._removal is None or not same_config(self._removal[0], key, self.domain.resolution):
            self._removal = (key, {}, {})
        fixed = target if target in bordering else -1
        _, values, tessellations = self._removal
        if fixed not in values:
            if any(abs(n.state.weight - weight) >= WEIGHT_MATCH for n in neighbours):
                values[fixed] = math.inf  # the bound assumes equal power weights
            else:
                ids = [n.robot_id for n in neighbours]
                gens = np.vstack([position[None], [n.position for n in neighbours]])
                near = [1 + ids.index(j) for j in bordering if j in ids]
                values[fixed] = removal_increase(
                    self.domain, gens, weight, near,
                    [1 + ids.index(fixed)] if fixed >= 0 else [], cell.cell_radius,
                    self.steps, self.method, tessellations).increase
        return values[fixed]


def config_key(position: np.ndarray, neighbours: Sequence[Neighbour]) -> np.ndarray:
    """``(1 + m, 3)`` the own position and the neighbours' (id, x, y), sorted by id."""
    rows = [(-1.0, *position)] + sorted((float(n.robot_id), *n.position) for n in neighbours)
    return np.array(rows, dtype=np.float64)


def same_config(a: np.ndarray, b: np.ndarray, tolerance: float) -> bool:
    """Same robots, none moved by ``tolerance`` [m] or more."""
    return a.shape == b.shape and bool(np.all(a[:, 0] == b[:, 0])) and \
        float(np.abs(a[:, 1:] - b[:, 1:]).max()) < tolerance
