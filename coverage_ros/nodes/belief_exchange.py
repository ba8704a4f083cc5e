"""The belief traffic of an exploring robot: what it tells the team, what it hears, what it
shows.

* ``observations`` (out, ``sensor_msgs/PointCloud2``, reliable): at ``observation_rate`` the own
  evidence of the cells that changed since the last message (at most ``observation_cells``) and
  the next ``refresh_cells`` of all the own evidence, round robin - so a lost message is
  repaired and a robot that joins late catches up within a few seconds;
* ``/<prefix><k>/observations`` (in): every other robot's evidence, merged as a grow-only state
  (:meth:`~coverage_ros.core.exploration.belief.Belief.merge`: repeats and reordering change
  nothing); a malformed cloud is dropped with a throttled warning;
* ``map`` (out, ``nav_msgs/OccupancyGrid``, transient local): the robot's belief at
  ``belief_rate``: -1 where nothing was seen, else round(100 p).

No map server and no merge node: every robot fuses what it hears itself.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

from nav_msgs.msg import OccupancyGrid
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2

from coverage_ros.core.exploration.belief import Belief, Evidence, joined
from coverage_ros.errors import CoverageError
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.qos import (
    LOCKSTEP_STATE_QOS,
    MAP_QOS,
    TEAM_QOS,
    quiet_publisher,
    quiet_subscription,
)
from coverage_ros.nodes.robot_config import ExploreIO
from coverage_ros.nodes.throttle import WarnThrottle

OBSERVATIONS = "observations"
OBSERVATIONS_TYPE = "sensor_msgs/msg/PointCloud2"


class BeliefExchange:
    """The ``observations`` and ``map`` topics of one exploring robot node."""

    def __init__(self, node: Node, belief: Belief, io: ExploreIO, throttle: WarnThrottle,
                 now, lockstep: Callable[[int, int, Evidence], None] | None = None) -> None:
        """``lockstep(sender, stamp [ns], evidence)`` takes the evidence heard instead of the
        belief (lock-step: merged at the tick it belongs to), and the robot's ticks publish its
        own (one message each time: :meth:`publish_observations` with ``joined``)."""
        self.node, self.belief, self.io = node, belief, io
        self._throttle = throttle
        self._now = now  # () -> sim time [s]
        self._lockstep = lockstep
        self._qos = TEAM_QOS if lockstep is None else LOCKSTEP_STATE_QOS
        self.heard: dict[int, object] = {}  # robot id -> subscription
        self.sent_cells = 0
        self.pub = node.create_publisher(PointCloud2, OBSERVATIONS, self._qos,
                                         event_callbacks=quiet_publisher())
        self.map_pub = node.create_publisher(OccupancyGrid, "map", MAP_QOS)
        if lockstep is None:
            node.create_timer(1.0 / io.observation_rate, self.publish_observations)
        node.create_timer(1.0 / io.belief_rate, self.publish_map)

    def listen(self, robot_id: int, topic: str) -> None:
        """Merge the evidence robot ``robot_id`` publishes on ``topic`` from now on."""
        if robot_id in self.heard:
            return
        self.heard[robot_id] = self.node.create_subscription(
            PointCloud2, topic, partial(self._on_observations, robot_id),
            self._qos, event_callbacks=quiet_subscription())

    def _on_observations(self, robot_id: int, msg: PointCloud2) -> None:
        try:
            evidence = conv.evidence_from_msg(msg, robot_id, self.belief.lattice)
        except (CoverageError, ValueError) as exc:
            self._throttle.warn(f"obs{robot_id}", f"dropped observations of robot {robot_id}: "
                                f"{exc}")
            return
        if self._lockstep is not None:
            self._lockstep(robot_id, conv.stamp_ns(msg.header.stamp), evidence)
        else:
            self.belief.merge(evidence)

    def publish_observations(self, joined_up: bool = False) -> bool:
        """The own changes and the next refresh chunk (``joined_up``: in one message); whether
        anything was sent."""
        stamp = conv.to_time_msg(self._now())
        parts = [e for e in (self.belief.take_changes(self.io.observation_cells),
                             self.belief.refresh_chunk(self.io.refresh_cells))
                 if e is not None and len(e.cells)]
        if joined_up and len(parts) > 1:
            parts = [joined(*parts)]
        for evidence in parts:
            self.pub.publish(conv.evidence_msg(evidence, self.belief.lattice, stamp))
            self.sent_cells += len(evidence.cells)
        return bool(parts)

    def publish_map(self) -> None:
        grid = self.belief.lattice.with_occupancy(self.belief.occupancy_percent())
        self.map_pub.publish(conv.grid_to_occupancy_grid(grid, conv.to_time_msg(self._now())))
