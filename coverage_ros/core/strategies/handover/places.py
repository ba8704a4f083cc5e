"""Where the robots of a team stood, compared whichever robot stands where: the closet escape's
memory of the moves a robot heard and the configurations they left from (:mod:`.protocol`).

A team may come back to where a move left from with other robots in the places (live robots
descend along their own paths, not the steps that priced a move), and the robot now where the
mover stood would make the same move: so every robot keeps the moves it heard
(:class:`HeardMove`: where the team stood when the claim was heard, where the claimer left from
and where it went) and does not make one of them again from the same places - each robot within
:data:`SAME_PLACE_SHARE` of its cell's radius of one of them, whichever robot stands
where, itself where the mover left from and the offered point where the mover went. Other
moves from there stay open (a team may need several moves from one configuration), but a
team back where a move left from shows the descent wrong there: a move priced by it must then
pay from every start, or save more than the heard move's claim
(:meth:`HeardMove.descent_terms`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching
from scipy.spatial.distance import cdist

from coverage_ros.core.strategies.base import Neighbour

#: Places of two teams within this share of the own cell's radius sqrt(area / pi) of each
#: other are the same configuration (another local optimum lies at least a room away).
SAME_PLACE_SHARE = 0.25


@dataclass(frozen=True)
class Places:
    """Where the robots of a team stood, whichever robot stood where."""

    ids: tuple[int, ...]  # every robot, sorted
    points: np.ndarray  # (n, 2) [m] their positions, in any order

    @classmethod
    def of(cls, robot_id: int, position: np.ndarray, neighbours: Sequence[Neighbour]
           ) -> Places:
        """The places of a robot at ``position`` [m] and the robots it hears."""
        ids = tuple(sorted([robot_id, *(n.robot_id for n in neighbours)]))
        return cls(ids, np.vstack([np.asarray(position, dtype=np.float64).reshape(1, 2),
                                   *(np.reshape(n.position, (1, 2)) for n in neighbours)]))

    def same(self, other: Places, near: float) -> bool:
        """The same robots, and a way to pair each place of one with its own place of the
        other within ``near`` [m] (a perfect matching of the pairs that near)."""
        if self.ids != other.ids:
            return False
        close = csr_matrix(cdist(self.points, other.points) <= near)
        return bool(np.all(maximum_bipartite_matching(close, perm_type="column") >= 0))


@dataclass(frozen=True)
class HeardMove:
    """A move a robot heard another make: where the team stood, where the mover left from and
    where it went [m], the saving its claim was priced at and who moved."""

    places: Places
    start: np.ndarray  # (2,) [m]
    end: np.ndarray  # (2,) [m]
    saving: float = 0.0  # the claim's ``claim_gain`` (units of H)
    mover: int = -1  # its robot id (-1: not known)

    def pulled_back(self, neighbours: Sequence[Neighbour], near: float) -> bool:
        """The mover, among ``neighbours``, stands within ``near`` [m] of where it left from."""
        return any(n.robot_id == self.mover
                   and float(np.hypot(*(np.asarray(n.position) - self.start))) <= near
                   for n in neighbours)

    def again(self, here: Places, position: np.ndarray, point: np.ndarray, near: float
              ) -> bool:
        """A robot at ``position`` with the team at ``here`` moving to ``point`` makes this
        move again: the same places, from its start to its end, each within ``near`` [m]."""
        return bool(np.hypot(*(np.asarray(position) - self.start)) <= near
                    and np.hypot(*(np.asarray(point) - self.end)) <= near
                    and here.same(self.places, near))

    @staticmethod
    def descent_terms(back: Sequence[HeardMove], neighbours: Sequence[Neighbour], near: float
                      ) -> tuple[float, bool]:
        """What moves heard from the places a team stands at again (``back``) ask of a move
        priced by the descent: the saving it must beat, the largest claim of those whose mover
        and the robot it displaced traded places; and whether it must pay from every start it
        is priced from (:meth:`.pricing.Prices.descent`), not from the most favourable: a
        mover is back within ``near`` [m] of where it left from (live, neighbours hold its cell
        while it drives, and it was pulled back), and a descent through a doorway that goes
        one way from some starts and the other way from the rest is what sends a mover so."""
        pulled = [m.pulled_back(neighbours, near) for m in back]
        failed = max((m.saving for m, p in zip(back, pulled, strict=True) if not p),
                     default=0.0)
        return failed, any(pulled)
