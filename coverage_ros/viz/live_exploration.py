"""The viewer's picture of an exploring team (no ROS): the team's merged belief over time.

The rerun bridge hands over every robot's evidence (:class:`~coverage_ros.core.exploration.
belief.Evidence`, what the robots exchange on ``observations``); :class:`ExplorationLayer` merges
it into one belief - what the team knows together - and every ``period`` seconds of sim time logs
its entropy under the cells and, against the true map of the world file, the explored fraction
and the false free share (:class:`~coverage_ros.core.exploration.scoring.ExplorationScorer`;
the area counted is the one reachable from where the robots were first seen).
"""

from __future__ import annotations

import numpy as np

from coverage_ros.core.exploration.belief import Belief, Evidence
from coverage_ros.core.exploration.scoring import ExplorationScorer
from coverage_ros.core.world.grid import GridMap
from coverage_ros.viz.recording import CoverageRecorder
from coverage_ros.viz.team import Schedule

#: Source id of the viewer's merged belief (no robot has it).
VIEWER_SOURCE = -1


class ExplorationLayer:
    """See module docstring."""

    def __init__(self, recorder: CoverageRecorder, truth: GridMap, solid: np.ndarray,
                 robot_radius: float, period: float = 2.0) -> None:
        self.rec = recorder
        self.truth, self.solid, self.radius = truth, solid, robot_radius
        lattice = GridMap(np.full(truth.shape, -1, np.int8), truth.resolution, truth.origin)
        self.belief = Belief(lattice, VIEWER_SOURCE)
        self.scorer: ExplorationScorer | None = None
        self._due = Schedule(period)
        self._logged_version = -1

    @property
    def lattice(self) -> GridMap:
        return self.belief.lattice

    def evidence(self, evidence: Evidence) -> None:
        self.belief.merge(evidence)

    def tick(self, t: float, positions: np.ndarray) -> None:
        """Log the belief and the scores if due at sim time ``t``; ``positions (n, 2)`` of the
        robots known (the first ones fix the area that counts)."""
        if not self._due.due(t) or self.belief.version == self._logged_version:
            return
        if self.scorer is None:
            if len(positions) == 0:
                return
            self.scorer = ExplorationScorer(self.truth, positions, self.radius, self.solid)
        snap = self.belief.snapshot()
        self._logged_version = snap.version
        score = self.scorer.score(snap)
        self.rec.set_time(t)
        self.rec.log_entropy(self.lattice, snap.entropy)
        self.rec.log_exploration(score.explored_fraction, score.false_free)
