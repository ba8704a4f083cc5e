"""The launcher's view of an exploring team: the team's merged belief, scored against the true
map (which only the launcher, the world node and the viewer read).

It hears every robot's ``observations`` (the same evidence the robots exchange) and merges them
into one belief - the union of what the team has seen - and samples, against the world file's
true map (:class:`~coverage_ros.core.exploration.scoring.ExplorationScorer`):

* ``explored_fraction``: share of the true free area reachable from the starts that the merged
  belief marks free; ``false_free``: share of the truly occupied cells it marks free;
* ``explored_at``: sim time (from ``ready_at``) when 0.5, 0.9, 0.95 and 0.99 were reached;
* ``series``: ``[t, explored_fraction, false_free]`` over the run.

At the end the merged belief is written as a map_server map, ``explored_map.yaml`` + ``.pgm``
(trinary: free where p <= 0.25, occupied where p >= 0.65, unknown otherwise).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2

from coverage_ros.core.exploration.belief import Belief
from coverage_ros.core.exploration.maps import trinary_grid
from coverage_ros.core.exploration.scoring import ExplorationScorer, milestones
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.map_server import write_map_yaml
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.errors import CoverageError
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.qos import LOCKSTEP_STATE_QOS, TEAM_QOS, quiet_subscription

#: Source id of the launcher's own (merged) belief: no robot has it.
TEAM_SOURCE = -1


class TeamExploration:
    """See module docstring."""

    def __init__(self, node: Node, world: WorldSpec, starts: np.ndarray, robot_ids: list[int],
                 radius: float, prefix: str = "robot_",
                 lockstep: Callable[[int, int, object], None] | None = None) -> None:
        """``lockstep(sender, stamp [ns], evidence)`` takes the evidence heard instead of the
        merged belief (lock-step: the monitor merges it at the ticks it samples)."""
        grid = world.grid
        lattice = GridMap(np.full(grid.shape, -1, np.int8), grid.resolution, grid.origin)
        self.belief = Belief(lattice, TEAM_SOURCE)
        self.scorer = ExplorationScorer(grid, starts, radius, world.solid)
        self.series: list[tuple[float, float, float]] = []
        self.dropped = 0
        self._lockstep = lockstep
        self.subs = [node.create_subscription(
            PointCloud2, f"/{prefix}{i}/observations",
            partial(self._on_observations, i),
            TEAM_QOS if lockstep is None else LOCKSTEP_STATE_QOS,
            event_callbacks=quiet_subscription()) for i in robot_ids]

    def _on_observations(self, robot_id: int, msg: PointCloud2) -> None:
        try:
            evidence = conv.evidence_from_msg(msg, robot_id, self.belief.lattice)
        except (CoverageError, ValueError):
            self.dropped += 1  # the robots warn about bad clouds themselves
            return
        if self._lockstep is not None:
            self._lockstep(robot_id, conv.stamp_ns(msg.header.stamp), evidence)
        else:
            self.belief.merge(evidence)

    def sample(self, t: float) -> float:
        """Score the merged belief at run time ``t`` [s]; the explored fraction."""
        score = self.scorer.score(self.belief.snapshot())
        self.series.append((round(t, 2), round(score.explored_fraction, 4),
                            round(score.false_free, 5)))
        return score.explored_fraction

    @property
    def explored(self) -> float:
        return self.series[-1][1] if self.series else 0.0

    def summary(self) -> dict:
        times = [s[0] for s in self.series]
        fractions = [s[1] for s in self.series]
        return {"explored_fraction": self.explored,
                "false_free": self.series[-1][2] if self.series else 0.0,
                "explored_at": milestones(times, fractions),
                "reachable_cells": self.scorer.reachable_cells,
                "dropped_messages": self.dropped,
                "series": [list(s) for s in self.series]}

    def write_map(self, out: Path) -> Path:
        """The merged belief as ``out/explored_map.yaml`` + ``.pgm``."""
        return write_map_yaml(trinary_grid(self.belief.snapshot()), out / "explored_map.yaml")
