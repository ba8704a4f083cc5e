"""Which neighbours a robot node listens to: their ``coverage_state`` (unless the process's
:class:`~coverage_ros.nodes.robot_shared.StateHub` does) and, exploring, their
``observations``. Found in the ROS graph once a second (seldom once the whole team is heard:
:class:`~coverage_ros.nodes.robot_graph.GraphLooks`), or in lock-step from the members each tick
lists (no graph: no discovery race decides what a robot sees)."""

from __future__ import annotations

from collections.abc import Callable, Iterable

from coverage_msgs.msg import RobotState

from coverage_ros.nodes.belief_exchange import OBSERVATIONS, OBSERVATIONS_TYPE
from coverage_ros.nodes.qos import LOCKSTEP_STATE_QOS, TEAM_QOS, quiet_subscription
from coverage_ros.nodes.robot_graph import GraphLooks, robot_topics, state_topics


class NeighbourInput:
    """``on_state(robot_id, msg)`` takes each state message; ``exchange()`` gives the node's
    BeliefExchange (None unless exploring); ``own_states``: subscribe to the states here."""

    def __init__(self, node, prefix: str, team_size: int, own_states: bool,
                 on_state: Callable[[int, RobotState], None], exchange, lockstep: bool) -> None:
        self.node, self.prefix, self.own_states = node, prefix, own_states
        self._on_state, self._exchange = on_state, exchange
        self._qos = LOCKSTEP_STATE_QOS if lockstep else TEAM_QOS
        self.subs: dict[int, object] = {}
        self.looks = GraphLooks(team_size)

    def discover(self) -> None:
        """Subscribe to every new neighbour found in the graph (k != own id)."""
        exchange = self._exchange()
        if (not self.own_states and exchange is None) or \
                not self.looks.due(len(self.subs) if exchange is None else -1):
            return
        names = self.node.get_topic_names_and_types()
        own = self.node.robot_id
        if exchange is not None:
            for rid, name in robot_topics(names, self.prefix, OBSERVATIONS, OBSERVATIONS_TYPE):
                if rid != own:
                    exchange.listen(rid, name)
        for rid, name in state_topics(names, self.prefix) if self.own_states else ():
            if rid == own or rid in self.subs or self.node.count_publishers(name) == 0:
                continue  # (no publisher: only subscribers so far, e.g. a monitor)
            self._subscribe(rid, name)
            self.node.get_logger().info(f"neighbour {rid} found on {name}")

    def roster(self, robot_ids: Iterable[int]) -> None:
        """Lock-step: listen to each of ``robot_ids`` (the members a tick lists)."""
        exchange = self._exchange()
        for rid in sorted(robot_ids):
            if rid == self.node.robot_id:
                continue
            if self.own_states and rid not in self.subs:
                self._subscribe(rid, f"/{self.prefix}{rid}/coverage_state")
            if exchange is not None:
                exchange.listen(rid, f"/{self.prefix}{rid}/{OBSERVATIONS}")

    def _subscribe(self, rid: int, name: str) -> None:
        self.subs[rid] = self.node.create_subscription(
            RobotState, name, lambda msg, rid=rid: self._on_state(rid, msg), self._qos,
            event_callbacks=quiet_subscription())
