"""What a robot of the closet escape keeps of its own moves (:mod:`.protocol`): where each left
from, and the judgement of its latest once the team has settled after it.

Each move is backed by a configuration next to it with H lower by at least the saving it had
to beat (:mod:`.bounds`), but the team's own steps need not reach that configuration (live
robots less still: where they stop is not exactly where Lloyd's steps end). So a robot keeps
where its moves left from: the robots it heard, their H over the cells of those robots
(:meth:`.pricing.Prices.heard_cost`) and the saving the move had to beat. It claims again,
hearing the same robots, only from a configuration whose H is below each of those by that
saving (:func:`blocked`): a team that came back to where a robot left from, or to no better,
does not send it again, and each robot's moves end.

A move can also end above where it left from: it is priced from the most favourable of its starts
(:meth:`.pricing.Prices.descent`), and the team's own steps need not reach the configuration
priced. So the mover judges its latest move once the team has settled after it (the gate of a
claim: every robot it hears settled, none claiming, the team still), busy until then. If the H
it hears, of the same robots, stands above what the move left from by more than the move had
to save, it claims the cell that now holds the place it left, at what going back saves (a move
that saves more goes first), and drives back there: a move it does not judge in turn, nor
keeps as a departure. The moves heard from the places it left stay kept, so the team, back
there, prices a move by the descent from every start (:class:`.places.HeardMove`). A
take-back outranked by another claim is judged again at the next settled update.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain


@dataclass(frozen=True)
class Departure:
    """Where a robot's move left from."""

    ids: tuple[int, ...]  # the robots it heard, sorted
    cost: float  # H over their cells and its own (units of H)
    saving: float  # what the move had to save (units of H)
    at: tuple[float, float] = (math.nan, math.nan)  # [m] where the robot stood
    back: bool = False  # the move takes back an earlier one (not judged itself)


def blocked(departures: Sequence[Departure], ids: tuple[int, ...], cost: float) -> bool:
    """A robot hearing ``ids`` (sorted) at H ``cost`` stands no better than where one of its
    ``departures`` left from, hearing the same robots: it claims nothing (module docstring)."""
    return any(d.ids == ids and not cost < d.cost - d.saving for d in departures)


@dataclass(frozen=True)
class TakeBack:
    """A claim that goes back to where a move left from."""

    holder: int  # generator index (1 + index among the robots heard) of the cell holding it
    gain: float  # what going back saves: how far above the departure the team stands
    point: np.ndarray  # (2,) [m] the place the move left


def judge(moved: Departure, ids: tuple[int, ...], cost: float, labels: np.ndarray,
          domain: CoverageDomain) -> TakeBack | None:
    """The take-back of ``moved`` (module docstring) for a team of the robots ``ids`` (sorted)
    standing at H ``cost``, whose tessellation labels every node with its generator (0: the
    own, -1: unreached), or None: the move stands (the team heard is another, or no higher
    than the move allowed, or the place is the own cell's again or not free)."""
    if ids != moved.ids or not cost > moved.cost + moved.saving:
        return None
    at = np.array(moved.at, dtype=np.float64)
    if not (np.all(np.isfinite(at)) and domain.is_free_point(at)):
        return None
    holder = int(labels[domain.snap(at)[0][0]])
    return TakeBack(holder, cost - moved.cost, at) if holder > 0 else None
