"""The frontier baseline of exploration (``frontier``): every robot goes to the frontier that is
best by its own distance and information gain, with no coordination, as explore_lite
(m-explore, and its ROS 2 port m-explore-ros2) sends goals to each robot's navigation.

explore_lite's planning cycle (``Explore::makePlan``), every ``1 / planner_frequency`` seconds
and whenever the current goal is reached:

1. find the frontiers (:func:`.frontiers.find_frontiers`), cheapest first; none left: stop;
2. take the cheapest one whose centroid is not within 5 cells (in x and in y) of a blacklisted
   goal; none: stop;
3. its centroid is the goal; the robot "makes progress" while the goal stays the same and its
   ``min_distance`` shrinks; after ``progress_timeout`` seconds without progress the goal is
   blacklisted and the next one is taken.

The robots share their maps (the same belief exchange the coordinated method uses), but not
their goals: two robots with similar maps often pick the same frontier - which is exactly what
the coordinated method is compared against. Defaults are m-explore-ros2's shipped parameters
(``planner_frequency`` 0.25 Hz, ``progress_timeout`` 30 s, ``potential_scale`` 3,
``gain_scale`` 1, ``min_frontier_size`` 0.75 m). A robot that finds no frontier left stays where
it is and looks again every cycle (explore_lite stops for good; a teammate's map may open new
frontiers, and the baseline should not lose by that).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np

from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    SharedState,
    Strategy,
    StrategyContext,
    StrategyDetails,
)
from coverage_ros.core.strategies.frontier.frontiers import Frontier, find_frontiers
from coverage_ros.errors import ConfigError

#: [cells] a frontier whose centroid lies this close (in x and in y) to a blacklisted goal is
#: blacklisted too (explore_lite's goalOnBlacklist tolerance).
BLACKLIST_CELLS = 5


@dataclass(frozen=True)
class FrontierParams:
    """Settings of the ``frontier`` strategy (m-explore-ros2's names and defaults)."""

    planner_frequency: float = 0.25  # [Hz] planning cycles (and on reaching a goal)
    progress_timeout: float = 30.0  # [s] without progress before a goal is blacklisted
    potential_scale: float = 3.0  # weight of the distance in the frontier cost
    gain_scale: float = 1.0  # weight of the frontier size in the cost
    min_frontier_size: float = 0.75  # [m] shorter frontiers are ignored

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                    and v >= 0):
                raise ConfigError.at(f"frontier.{f.name}", "must be a finite number >= 0", v)
        if self.planner_frequency <= 0:
            raise ConfigError.at("frontier.planner_frequency", "must be > 0 [Hz]",
                                 self.planner_frequency)


@dataclass(frozen=True)
class FrontierDetails(StrategyDetails):
    frontiers: int  # frontiers found in the last planning cycle
    blacklisted: int  # goals given up so far
    goal_frontier_size: int  # [cells] of the frontier pursued (0: none)


class FrontierStrategy(Strategy):
    """See module docstring."""

    name: ClassVar[str] = "frontier"
    Params: ClassVar[type] = FrontierParams
    params: FrontierParams
    explores: ClassVar[bool] = True

    def __init__(self, context: StrategyContext, params: FrontierParams | None = None) -> None:
        super().__init__(context, params)
        self.goal: np.ndarray | None = None
        self.blacklist: list[np.ndarray] = []
        self.next_plan = -math.inf  # [s] time of the next planning cycle
        self.last_progress = 0.0  # [s]
        self.prev_distance = math.inf  # [m]
        self.found = 0
        self.pursued: Frontier | None = None
        self.done = False

    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        if obs.belief is None:
            raise ConfigError.at("frontier", "needs the robot's belief of the map")
        p = obs.position
        reached = self.goal is not None and \
            float(np.hypot(*(self.goal - p))) < self.context.convergence_tolerance * 4
        if obs.time >= self.next_plan or reached:
            self.next_plan = obs.time + 1.0 / self.params.planner_frequency
            self._plan(obs)
        goal = None if self.goal is None else self.goal.copy()
        return Decision(
            goal=goal if goal is not None else p.copy(), velocity=None,
            cell=np.zeros(0, np.int64),
            shared=SharedState(position=p.copy(), weight=self.context.weight),
            converged=self.done, cost=0.0, mass=0.0,
            mode="done" if self.done else "frontier",
            details=FrontierDetails(frontiers=self.found, blacklisted=len(self.blacklist),
                                    goal_frontier_size=0 if self.pursued is None
                                    else self.pursued.size))

    def _plan(self, obs: Observation) -> None:
        """One planning cycle (see module docstring)."""
        assert obs.belief is not None
        par = self.params
        frontiers = find_frontiers(obs.belief, obs.position, self.context.robot.radius,
                                   par.potential_scale, par.gain_scale, par.min_frontier_size)
        self.found = len(frontiers)
        res = obs.belief.lattice.resolution
        for best in frontiers:
            if self._blacklisted(best.centroid, res):
                continue
            same = self.goal is not None and bool(np.all(self.goal == best.centroid))
            if not same or self.prev_distance > best.min_distance:
                self.last_progress = obs.time
                self.prev_distance = best.min_distance
            self.goal, self.pursued, self.done = best.centroid.copy(), best, False
            if obs.time - self.last_progress <= par.progress_timeout:
                return
            self.blacklist.append(best.centroid.copy())  # no progress: give it up
        # No frontier left: stay (and look again next cycle, in case a teammate's map opens
        # new ones; explore_lite itself stops for good).
        self.goal, self.pursued, self.done = None, None, True

    def _blacklisted(self, point: np.ndarray, res: float) -> bool:
        tol = BLACKLIST_CELLS * res
        return any(abs(point[0] - b[0]) < tol and abs(point[1] - b[1]) < tol
                   for b in self.blacklist)
