"""What the robots of one process share (README "Several robots per process").

``robot_node`` runs one robot per process; ``robot_container`` runs several (the ROS 2
composition idiom: each still its own node in its own namespace, with the same topics and
parameters). The robots of one process share:

* :class:`SharedInputs` - world files, read once per path, and coverage domains (the inflated
  map, its graph and density and every table computed on them), built once per map, robot
  radius, density, connectivity and metric: a robot's strategy only reads its domain, and the
  domain's lazily filled tables are the same whoever fills them;
* update turns and budget (container only): one robot's coverage update runs at a time, the
  others wait their turn (the one whose last update is oldest first), so the executor thread
  (tracking, safety filter, messages) never competes with more than one busy thread for the
  GIL, and the process holds one update's temporary arrays, not K; the robots' update CPU
  budgets are pooled (``nodes/update_worker.py``);
* :class:`StateHub` (container only) - one subscription per neighbour's ``coverage_state``,
  parsed once and handed to every local robot but its sender, instead of one per robot and
  neighbour (with K robots per process, a team of N sends N * N / K messages instead of N * N);
* the ``/clock`` subscription (container only, ``robot_container.ContainerNode``): the robots'
  clocks follow the container node's time source instead of waking each robot at 10 Hz.

No robot-specific state is shared: each keeps its own controller, strategy, caches and update
thread.
"""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Callable
from pathlib import Path

from coverage_msgs.msg import RobotState

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.world import load_planar_world
from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.metric import zeta_on_grid
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.qos import LOCKSTEP_STATE_QOS, TEAM_QOS, quiet_subscription
from coverage_ros.nodes.robot_graph import state_topics
from coverage_ros.nodes.update_worker import UpdatePool, UpdateTurns
from coverage_ros.worlds import resolve_world_path


def grid_digest(grid: GridMap) -> bytes:
    """A digest of what a domain is built from on ``grid`` (cells, resolution, origin): two
    copies of one map (e.g. the same ``/map`` message received by two robots) give the same."""
    h = hashlib.blake2b(digest_size=16)
    h.update(repr((grid.occupancy.shape, grid.resolution, grid.origin)).encode())
    h.update(grid.occupancy.tobytes())
    return h.digest()


class SharedInputs:
    """World files and coverage domains of the robots of one process (see module docstring);
    safe to call from any thread."""

    def __init__(self, update_slots: int | None = None) -> None:
        """``update_slots``: coverage updates of the process's robots that may run at once
        (None: no limit, one robot per process); with slots, the robots' update CPU budgets
        are pooled too (``update_pool``, :class:`~coverage_ros.nodes.update_worker.UpdatePool`)."""
        self.update_slots = None if update_slots is None else UpdateTurns(update_slots)
        self.update_pool = None if update_slots is None else UpdatePool()
        self._lock = threading.Lock()
        self._worlds: dict[str, WorldSpec] = {}
        # key -> (domain, the objects the key names by id: kept alive so no id is reused)
        self._domains: dict[tuple, tuple[CoverageDomain, tuple]] = {}
        self.domains_built = 0

    def world(self, name: str) -> WorldSpec:
        """The world ``name`` (a path or a shipped world), loaded once per process."""
        path = str(Path(resolve_world_path(name)).resolve())
        with self._lock:
            if path not in self._worlds:
                self._worlds[path] = load_planar_world(Path(path))
            return self._worlds[path]

    def domain(self, grid: GridMap, robot_radius: float, density, connectivity: int,
               unknown_is_free: bool, metric) -> CoverageDomain:
        """``CoverageDomain.from_grid`` with the world's ``metric`` (None: Euclidean), built
        once per distinct input. ``density`` and ``metric`` are compared by identity (a
        world loaded through :meth:`world` gives every robot the same objects)."""
        key = (grid_digest(grid), float(robot_radius), id(density), int(connectivity),
               bool(unknown_is_free), id(metric))
        with self._lock:
            held = self._domains.get(key)
            if held is None:
                domain = CoverageDomain.from_grid(
                    grid, robot_radius, density, connectivity=connectivity,
                    unknown_is_free=unknown_is_free, zeta=zeta_on_grid(metric, grid))
                held = self._domains[key] = (domain, (density, metric))
                self.domains_built += 1
            return held[0]


class StateHub:
    """The neighbour states of a process's robots: one subscription per ``coverage_state``
    topic of the team, each message parsed once and given to every local robot but its
    sender, checked and built into a state once. ``robots`` have ``robot_id`` and
    ``take_state(sender, values, parsed)``; ``node`` owns the subscriptions; ``warn(key,
    text)`` reports a dropped message."""

    def __init__(self, node, robots: list, prefix: str,
                 warn: Callable[[str, str], object]) -> None:
        self.node, self.robots, self.prefix, self._warn = node, list(robots), prefix, warn
        self.subscriptions: dict[int, object] = {}
        self.received = self.delivered = 0

    def discover(self) -> None:
        """Subscribe to every new neighbour's state topic that has a publisher."""
        for rid, name in state_topics(self.node.get_topic_names_and_types(), self.prefix):
            if rid in self.subscriptions or self.node.count_publishers(name) == 0:
                continue  # only subscribers so far (e.g. a monitor): not a robot yet
            self._subscribe(rid, name, TEAM_QOS)
            self.node.get_logger().info(f"robot {rid} found on {name}")

    def roster(self, tick) -> None:
        """Lock-step: subscribe to the state of every robot the tick lists."""
        for rid in sorted(tick.robots):
            if rid not in self.subscriptions:
                self._subscribe(rid, f"/{self.prefix}{rid}/coverage_state", LOCKSTEP_STATE_QOS)

    def _subscribe(self, rid: int, name: str, qos) -> None:
        self.subscriptions[rid] = self.node.create_subscription(
            RobotState, name, lambda msg, rid=rid: self.on_state(rid, msg), qos,
            event_callbacks=quiet_subscription())

    def on_state(self, sender: int, msg) -> None:
        self.received += 1
        try:
            values = conv.coverage_state_values(msg)
        except ValueError as exc:
            self._warn(f"state{sender}", f"dropped coverage_state of robot {sender}: {exc}")
            return
        parsed: dict = {}  # checked and built once per map extent, for every robot
        stamp = conv.stamp_ns(msg.header.stamp)
        for robot in self.robots:
            if robot.robot_id != sender:
                robot.take_state(sender, values, parsed, stamp)
                self.delivered += 1
