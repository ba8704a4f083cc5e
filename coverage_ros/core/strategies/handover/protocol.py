"""Closet escape by handover: a settled robot leaves its cell for a neighbour's when the pair's
bound says H drops (:mod:`.bounds`), after a claim its neighbour grants.

Every robot publishes, with its state (``SharedState.extra``):

* ``settled`` (1/0): its Lloyd step is below ``escape_settle`` and ``escape_settle_share`` of its
  cell's radius sqrt(area / pi), or it stands still (:mod:`.stillness`: not moving, or dithering
  within that step threshold);
* ``offer_gain``, ``offer_x``, ``offer_y``, ``offer_base``: settled, what splitting its own cell
  with a second generator at (x, y) would save, and its cell's cost (:func:`.split.split_offer`;
  gain 0: no offer); ``offer2_gain``, ``offer2_x``, ``offer2_y``: a second split, in the part of
  the cell the first leaves to it (:func:`.split.split_offers`: a cell spanning two rooms);
* ``claim`` (a robot id, -1: none) and ``claim_gain``: the cell it asks to move into and the
  bound's saving;
* ``grant``: the one claimant it lets in (-1: none);
* ``relocating``, ``to_x``, ``to_y``: on its way to a claimed cell's point, and that point (its
  neighbours' cells count its generator where it left from until it arrives:
  :mod:`.published`).

Robot i claims neighbour j (any robot it hears: the offer is j's, the removal i's own, so the bound
needs no common border) when i and every robot it hears are settled and none of them claims (one
move at a time: a robot on its way leaves its cell to the others, who spread into it until it
arrives, so a bound priced meanwhile would price a passing state; of claims made at once, all but
the one of the highest priority - saving, then lower id - are dropped before a grant), j neither
claims nor grants another, and ``offer_gain(j) - removal_increase(i)`` exceeds ``escape_gain``
times the pair's cost ``H_i + H_j`` and ``escape_team_gain`` times the H of all i hears (on a
large map a robot crosses it for minutes, meanwhile H rises: only for a move that matters to
the team). When no offer passes so and i stood still at its last update or dithers
(Lloyd's end), the same test runs on the joint bound instead (:func:`.bounds.joint_change`: i at
j's offered point, every robot whose cell touches i's or j's re-spreading, against the same steps
without the move), which sees moves that pay only once the neighbours of both cells shift along; if
none passes that either and ``escape_joint_rings`` allows, on the joint bound of wider rings of
cells (the cells touching those too), which sees a robot shut in a corner whose one neighbour
cannot take its cell alone; such a move is priced by where the team's own generalized Lloyd
descent from it ends (:func:`.bounds.descent_change`). If still none passes, the largest
``escape_descent_offers`` offers are priced by that descent alone, every robot i hears
descending: a move that pays only once robots far from both cells shift along (rooms off a
long corridor); if none of them pays, so is a point in each other room of the cells those
offers split (:func:`.split.room_offers` on i's own tessellation of what it hears, with
``escape_descent_rooms`` starts): a robot covering several rooms from a corridor offers the
splits that save most in its cell alone, which need not be where a robot moving in pays
once the team re-spreads. The robots price so one per update of a settled configuration,
the one whose cell costs least first (its leaving costs least), each descent stopping as
soon as the move pays; the first move found is claimed and the others need not price.
Robot j grants the claim of the highest priority (saving, then lower id) among those on it
unless it claims itself. With ``escape_still`` > 0 a robot claims only once the team stands
(:class:`.stillness.TeamStillness`).
Granted, i drives to j's offered point (mode ``relocate``), keeping its claim, so that j lets
nobody else in and i's neighbours do not leave meanwhile; there it drops the claim and waits
``escape_cooldown`` updates before it may claim again (hysteresis), busy meanwhile (not
converged: it may still move). A claim not granted within ``escape_wait`` updates, or whose
target grants another, is dropped the same way.

Each move is backed by a configuration next to it with H lower by at least ``escape_gain`` of
a pair's cost (:mod:`.bounds`), and the cooldown keeps a robot from moving back and forth; a
robot claims again, hearing the robots it heard where a move of its own left from, only from a
lower H, and a move that ends above where it left from is taken back (:mod:`.departures`);
every robot keeps the moves it heard, making none again from the same places (:mod:`.places`).
What a robot uses is its own cell, the generators and published values of the robots it
hears (its bordering neighbours' cells, and for the joint bound the target's and those that
touch either, are tessellated from them), nothing else; the protocol is deterministic.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from coverage_ros.core.geodesic.cell import CellResult
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies.base import Neighbour
from coverage_ros.core.strategies.handover.departures import Departure, blocked, judge
from coverage_ros.core.strategies.handover.places import SAME_PLACE_SHARE, HeardMove, Places
from coverage_ros.core.strategies.handover.pricing import (
    WEIGHT_MATCH,
    Prices,
    config_key,
    same_config,
)
from coverage_ros.core.strategies.handover.published import (
    NONE,
    Offer,
    destination,
    idle,
    offers_of,
    rank,
    value,
)
from coverage_ros.core.strategies.handover.settings import HandoverSettings
from coverage_ros.core.strategies.handover.split import SplitOffer
from coverage_ros.core.strategies.handover.stillness import STILL_UPDATES, Stillness, TeamStillness

#: A relocating robot has arrived within this many convergence tolerances of its point, or
#: this many grid cells, whichever is more (a goal is a cell centre).
ARRIVAL_TOLERANCES, ARRIVAL_CELLS = 3.0, 2.0
#: [configurations] relocated from, remembered per robot (the latest)
DEPARTURES = 8


@dataclass(frozen=True)
class HandoverStep:
    """What the protocol makes of one update."""

    goal: np.ndarray | None  # (2,) [m] the relocation point, None: the Lloyd goal stands
    extra: dict[str, float]  # what to publish
    busy: bool  # a claim, grant or relocation is under way (the team has not settled)


@dataclass
class Handover:
    """One robot's side of the protocol (module docstring)."""

    robot_id: int
    domain: CoverageDomain
    settings: HandoverSettings
    method: str = "auto"
    claim: int = -1  # robot id of the cell claimed
    claim_gain: float = 0.0
    claim_age: int = 0  # [updates]
    target: np.ndarray | None = None  # (2,) [m] the claimed cell's offered point
    relocating: bool = False
    cooldown: int = 0  # [updates]
    relocations: int = 0  # moves made
    _stillness: Stillness = field(default_factory=Stillness, repr=False)
    _team_still: TeamStillness = field(init=False, repr=False)
    _awaits_still: bool = field(default=False, repr=False)
    #: updates that reached the descent's pricing in one configuration (its key); waiting
    _turns: tuple[np.ndarray, int] | None = field(default=None, repr=False)
    _awaits_turn: bool = False
    #: (ids heard, their H, the saving to beat) where the claim was made / moves were made
    _claimed_from: Departure | None = field(default=None, repr=False)
    _departures: list[Departure] = field(default_factory=list, repr=False)
    #: the latest own move, until the team has settled after it and it is judged
    _judging: Departure | None = field(default=None, repr=False)
    #: claims heard, by claimer id: (where the claimer stood [m], its target, the team's
    #: places then, the claim's saving), kept in ``_moves`` once it is heard relocating
    _heard_claims: dict[int, tuple[np.ndarray, int, Places, float]] = field(
        default_factory=dict, repr=False)
    _moves: list[HeardMove] = field(default_factory=list, repr=False)
    prices: Prices = field(init=False, repr=False)  # what it priced, per configuration

    def __post_init__(self) -> None:
        s = self.settings
        self.prices = Prices.of(self.domain, self.method, s)
        self._team_still = TeamStillness(s.still)

    def step(self, position: np.ndarray, weight: float, cell: CellResult,
             neighbours: Sequence[Neighbour], bordering: Sequence[int],
             convergence_tolerance: float, arrived: bool = False) -> HandoverStep:
        """One update: ``cell`` is the own cell at ``position`` [m], ``bordering`` the ids of
        the neighbours whose cells border it; ``arrived``: a neighbour has just ended a
        relocation away from where its generator counted meanwhile."""
        s = self.settings
        by_id = {n.robot_id: n for n in neighbours}
        self._awaits_turn = self._awaits_still = False
        if self.relocating:
            self._team_still.restart()
            return self._transit(position, by_id, convergence_tolerance)
        if self.cooldown > 0:
            self.cooldown -= 1
        step = float(np.hypot(*(cell.goal - position)))
        # standing still counts too: a step the robot does not take (monotone rule, blocked)
        stood = self._stillness
        stood.note(position, convergence_tolerance, restart=arrived)
        settle = s.settle_below(self.domain.area_of(cell.nodes))
        dithers = stood.dithers(settle)
        still = stood.stands() or dithers
        settled = step < settle or still
        key = config_key(position, neighbours)
        self._team_still.note(key)
        self._hear_moves(position, neighbours)
        offers: list[SplitOffer] = []  # the own (published)
        if settled and self.claim < 0:
            offers = self.prices.offers(key, cell, weight)
        claimants = sorted(((value(n, "claim_gain"), -n.robot_id) for n in neighbours
                            if value(n, "claim", NONE) == self.robot_id), reverse=True)
        mine = (self.claim_gain, -self.robot_id)
        if self.claim >= 0 and claimants and claimants[0] > mine:
            self._drop()  # a neighbour with a higher priority wants into this cell
        if self.claim >= 0:
            self._follow_claim(by_id)
        elif (settled and self.cooldown == 0 and not claimants
              and all(value(n, "settled") > 0 for n in neighbours)):
            if self._team_still.still(settle):
                if self._judging is not None:
                    self._judge(key, position, weight, neighbours)
                if self.claim < 0 and self._judging is None:
                    self._consider(key, position, weight, cell, neighbours, bordering,
                                   stopped=stood.moved < convergence_tolerance or dithers)
            else:  # (the team still creeps: busy, it may claim once it stands)
                self._awaits_still = True
        grant = NONE if self.claim >= 0 or not claimants else float(-claimants[0][1])
        if self.relocating:
            self.relocations += 1
        extra = idle()
        extra.update(settled=float(settled and self.claim < 0), claim=float(self.claim),
                     claim_gain=self.claim_gain if self.claim >= 0 else 0.0, grant=grant)
        if self.relocating:
            extra.update(self._heading())
        if offers and grant == NONE and self.claim < 0:
            extra.update(offer_gain=offers[0].gain, offer_x=float(offers[0].point[0]),
                         offer_y=float(offers[0].point[1]), offer_base=offers[0].base)
            if len(offers) > 1:
                extra.update(offer2_gain=offers[1].gain, offer2_x=float(offers[1].point[0]),
                             offer2_y=float(offers[1].point[1]))
        # standing still off the Lloyd goal, not yet settled: not done either (may claim later)
        waiting = 0 < stood.still_for < STILL_UPDATES and step >= settle and not still
        # in its cooldown (after a move or a dropped claim) it may claim again once it ends:
        # not done either (all claims made at once but one are dropped, so at Lloyd's end
        # most of a team may be cooling down together)
        # (nor while it waits for its turn to price by the descent, or for the team to stand)
        busy = (self.claim >= 0 or grant != NONE or waiting or self.cooldown > 0
                or self._awaits_turn or self._awaits_still or self._judging is not None)
        return HandoverStep(self.target.copy() if self.relocating else None, extra, busy)

    def _transit(self, position: np.ndarray, by_id: dict[int, Neighbour],
                 convergence_tolerance: float) -> HandoverStep:
        """Under way to the claimed cell's point: done on arrival, after ``transit`` updates,
        or when the claimed robot is gone."""
        self.claim_age += 1
        target = self.target
        assert target is not None  # set with the claim, kept while relocating
        arrive = max(ARRIVAL_TOLERANCES * convergence_tolerance,
                     ARRIVAL_CELLS * self.domain.resolution)
        near = float(np.hypot(*(target - position))) < arrive
        if near or self.claim_age > self.settings.transit or self.claim not in by_id:
            moved = self._claimed_from
            self._drop()
            if moved is not None and not moved.back:
                self._judging = moved  # judged once the team has settled after it
            return HandoverStep(None, idle(), busy=True)
        extra = idle()
        extra.update(claim=float(self.claim), claim_gain=self.claim_gain, **self._heading())
        return HandoverStep(target.copy(), extra, busy=True)

    def _heading(self) -> dict[str, float]:
        """Published while relocating: where to (:func:`.published.destination`)."""
        assert self.target is not None  # set with the claim, kept while relocating
        return {"relocating": 1.0, "to_x": float(self.target[0]), "to_y": float(self.target[1])}

    def _hear_moves(self, position: np.ndarray, neighbours: Sequence[Neighbour]) -> None:
        """Where the moves of the robots it hears leave from (module docstring): the places of
        the team a claim heard is made at, kept once its claimer relocates (heard relocating,
        or gone from where it claimed when its claim ends between two updates)."""
        arrive = ARRIVAL_CELLS * self.domain.resolution
        for n in neighbours:
            rid, target = n.robot_id, int(value(n, "claim", NONE))
            heard = self._heard_claims.get(rid)
            going = value(n, "relocating") > 0
            if going or (heard is not None and target != heard[1]
                         and float(np.hypot(*(n.position - heard[0]))) > arrive):
                if heard is not None:
                    self._heard_claims.pop(rid)
                    move = HeardMove(heard[2], heard[0],
                                     np.array(destination(n), dtype=np.float64), heard[3], rid)
                    self._moves = [*self._moves, move][-DEPARTURES:]
            elif target < 0:
                self._heard_claims.pop(rid, None)
            elif heard is None or heard[1] != target:
                self._heard_claims[rid] = (np.array(n.position, dtype=np.float64), target,
                                           Places.of(self.robot_id, position, neighbours),
                                           value(n, "claim_gain"))

    def _follow_claim(self, by_id: dict[int, Neighbour]) -> None:
        """A claim made earlier: relocate once granted, drop it when refused, stale or
        outranked by another claim made meanwhile (one move at a time)."""
        j = by_id.get(self.claim)
        self.claim_age += 1
        grant = NONE if j is None else value(j, "grant", NONE)
        mine = (self.claim_gain, -self.robot_id)
        outranked = any(value(n, "claim", NONE) >= 0
                        and (value(n, "claim_gain"), -n.robot_id) > mine for n in by_id.values())
        if j is not None and grant == self.robot_id:
            self.relocating, self.claim_age = True, 0
            if self._claimed_from is not None and self._claimed_from.back:
                self._judging = None  # taking its move back: nothing left to judge
            elif self._claimed_from is not None:
                self._departures = [*self._departures, self._claimed_from][-DEPARTURES:]
        elif j is None or grant != NONE or outranked or self.claim_age > self.settings.wait:
            self._drop()

    def _consider(self, key: np.ndarray, position: np.ndarray, weight: float,
                  cell: CellResult, neighbours: Sequence[Neighbour],
                  bordering: Sequence[int], stopped: bool) -> None:
        """Unless a robot it hears claims: the offer that beats the own removal most, if by
        enough; else, standing still (``stopped``: Lloyd's end), by the joint bounds."""
        if any(value(n, "claim", NONE) >= 0 for n in neighbours):
            return  # one move at a time (module docstring)
        here = Places.of(self.robot_id, position, neighbours)
        near = SAME_PLACE_SHARE * math.sqrt(self.domain.area_of(cell.nodes) / math.pi)

        def made(o: Offer) -> bool:  # (a move heard from these places: module docstring)
            return any(m.again(here, position, o.point, near) for m in self._moves)

        offers = [o for n in neighbours for o in offers_of(n)
                  if value(n, "claim", NONE) < 0 and value(n, "grant", NONE) == NONE
                  and abs(n.state.weight - weight) < WEIGHT_MATCH
                  and self.domain.is_free_point(o.point) and not made(o)]
        if not offers:
            return
        s = self.settings  # a move saves ``escape_gain`` of the pair's cost, and of the H heard
        floor = s.team_gain * self.prices.heard_cost(key, position, neighbours, weight) \
            if s.team_gain > 0 else 0.0

        def need(o: Offer) -> float:
            return max(s.gain * (cell.cost + o.base), floor)

        # the removal bound per target: one held fixed when it borders the own cell
        removal = {o.robot_id: self.prices.removal(key, position, weight, cell, neighbours,
                                                   bordering, o.robot_id)
                   for o in offers}
        best, saving = self._best(offers, need, {
            o.key: o.gain - removal[o.robot_id] for o in offers})
        rings = 1
        while best is None and stopped and rings <= self.settings.joint_rings:
            # no pair's bound suffices: both cells' neighbours re-spreading, then theirs too
            best, saving = self._best(offers, need, {
                o.key: -self.prices.joint(key, position, weight, neighbours, o, rings)
                for o in offers})
            rings += 1
        back = [m for m in self._moves if here.same(m.places, near)]  # (module docstring)
        if best is None and stopped and self.settings.descent_offers > 0:
            # no bound sees it: where the whole team's own descent goes from the largest offers
            # (what the moves heard from here ask), by one robot per update, the least costly
            failed, every = HeardMove.descent_terms(back, neighbours, near)

            def beyond(o: Offer) -> float:
                return max(need(o), failed)

            if self._turns is None or not same_config(self._turns[0], key, self.domain.resolution):
                self._turns = (key, 0)
            self._turns = (key, self._turns[1] + 1)  # (updates here, this one counted)
            if self._turns[1] <= rank(self.robot_id, cell.cost, neighbours):
                self._awaits_turn = True
                return
            largest = sorted(offers, key=lambda o: (-o.gain, o.key))[
                :self.settings.descent_offers]
            best, saving = self._best(largest, beyond, {
                o.key: -self.prices.descent(key, position, weight, neighbours, o, beyond(o),
                                            every)
                for o in largest})
            if best is None and self.settings.descent_rooms > 1:
                # none of them pays: a point in every other room of the cells they split
                rooms = [o for j in dict.fromkeys(o.robot_id for o in largest)
                         for o in self.prices.rooms(key, position, weight, neighbours, j,
                                                    offers) if not made(o)]
                if rooms:
                    best, saving = self._best(rooms, beyond, {
                        o.key: -self.prices.descent(key, position, weight, neighbours, o,
                                                    beyond(o), every)
                        for o in rooms})
        if best is None:
            return
        ids = tuple(sorted(n.robot_id for n in neighbours))
        H = self.prices.heard_cost(key, position, neighbours, weight)
        if blocked(self._departures, ids, H):
            return  # no better than where a move of its own left from
        self.claim, self.claim_gain, self.claim_age = best.robot_id, saving, 0
        self.target = best.point.copy()
        self._claimed_from = Departure(ids, H, need(best), (float(position[0]),
                                                            float(position[1])))

    def _judge(self, key: np.ndarray, position: np.ndarray, weight: float,
               neighbours: Sequence[Neighbour]) -> None:
        """The own latest move, the team settled after it: taken back (a claim on the cell
        holding the place it left) or kept (:mod:`.departures`)."""
        assert self._judging is not None  # (called only while a move is being judged)
        if any(value(n, "claim", NONE) >= 0 for n in neighbours):
            return  # one move at a time (module docstring)
        ids = tuple(sorted(n.robot_id for n in neighbours))
        H = self.prices.heard_cost(key, position, neighbours, weight)
        known, _ = self.prices.known(key, position, neighbours)
        back = judge(self._judging, ids, H, known.labels, self.domain)
        if back is None:
            self._judging = None  # the move stands
            return
        self.claim, self.claim_gain, self.claim_age = \
            neighbours[back.holder - 1].robot_id, back.gain, 0
        self.target = back.point
        self._claimed_from = Departure(ids, H, 0.0, back=True)

    @staticmethod
    def _best(offers: Sequence[Offer], need: Callable[[Offer], float],
              savings: dict[tuple[int, int], float]) -> tuple[Offer | None, float]:
        """The offer of the largest saving (then the lower id, then the first of a robot's
        two), if it beats what the offer ``need``s to save."""
        best = max(offers, key=lambda o: (savings[o.key], -o.robot_id, -o.key[1]))
        saving = savings[best.key]
        if not saving > need(best):
            return None, 0.0
        return best, saving

    def _drop(self) -> None:
        self.claim, self.claim_gain, self.claim_age = -1, 0.0, 0
        self.relocating, self.target = False, None
        self.cooldown = self.settings.cooldown

