"""One robot node's lock-step side (``lockstep: true``; README "Lock-step simulation").

The node's inputs - pose, scans, neighbours' states, exploring evidence - go into an
:class:`~coverage_ros.core.lockstep.Inbox` instead of the controller, and the world's ticks
drive the robot instead of its timers: at tick ``k`` (:meth:`RobotLockstep.step`, on the
process's :class:`~coverage_ros.nodes.lockstep_member.LockstepDriver` thread) the robot takes
the states its neighbours published at ``k - 1``, its pose and scans of ``k``, runs its coverage
update when one is due (every ``control_rate`` of sim time, first at tick 1, when every robot
knows every other's start), computes its command, publishes its evidence when due (exploring,
every ``observation_rate``) and its ``coverage_state`` stamped ``t_k``. Nothing it computes
depends on when a message arrived or how long anything took.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from coverage_ros.core.lockstep import Inbox, Tick, ticks_per
from coverage_ros.core.lockstep.inbox import EVIDENCE_KEY
from coverage_ros.nodes import conversions as conv

if TYPE_CHECKING:  # (the driver module imports this one's users)
    from coverage_ros.nodes.lockstep_member import LockstepDriver


class RobotLockstep:
    """See module docstring; ``node`` is the :class:`~coverage_ros.nodes.robot_node.RobotNode`."""

    def __init__(self, node) -> None:
        self.node = node
        self.inbox = Inbox(node.robot_id)
        self.driver: LockstepDriver | None = None  # the process's, set by whoever made it
        self._posed = False
        self.evidence_stamp: float | None = None  # [s] of the newest evidence published

    def _notify(self) -> None:
        if self.driver is not None:
            self.driver.notify()

    # ------------------------------------------------------------------ inputs (any thread)
    def put_pose(self, stamp: int, pose) -> None:
        self._posed = True
        self.inbox.put_pose(stamp, pose)
        self._notify()

    def put_scan(self, stamp: int, msg) -> None:
        self.inbox.put_scan(stamp, msg)
        self._notify()

    def put_state(self, sender: int, stamp: int, values: dict[str, float]) -> None:
        self.inbox.put_state(sender, stamp, values)
        self._notify()

    def put_evidence(self, sender: int, stamp: int, evidence) -> None:
        self.inbox.put_evidence(sender, stamp, evidence)
        self._notify()

    # ------------------------------------------------------------------ the driver's calls
    @property
    def robot_id(self) -> int:
        return self.node.robot_id

    def joinable(self) -> bool:
        return self.node.controller is not None and self._posed

    def roster(self, tick: Tick) -> None:
        self.node.neighbours.roster(tick.robots)

    def missing(self, tick: Tick) -> list[str]:
        node = self.node
        if node.controller is None:
            return ["map"]
        return self.inbox.missing(tick, scan=node.uses_scan, evidence=node.exchange is not None)

    def step(self, tick: Tick) -> tuple[float, float] | None:
        node, c = self.node, self.node.controller
        now = tick.time
        node.tick_time = now
        got = self.inbox.take(tick, evidence=node.exchange is not None)
        previous = tick.previous * 1e-9
        for rid in sorted(got.states):
            values = {k: v for k, v in got.states[rid].items() if k != EVIDENCE_KEY}
            why = c.neighbours.receive(rid, values, previous)
            if why:
                node._warn(f"state{rid}", f"dropped coverage_state of robot {rid}: {why}")
        for _, _, evidence in got.evidence:
            c.belief.merge(evidence)
        if got.pose is not None:
            c.set_pose(got.pose, now)
            node.poses.add(now, got.pose)
        for _, msg in got.scans:
            node.scans.use(msg)
        if tick.due(ticks_per(1.0 / node.config.control_rate, tick.period)):
            node._update(now)
        command = None
        if node.config.drive:
            command = c.command(now, tick.period)
            node.publish_cmd(*command, now)
        extra = {}
        if node.exchange is not None:
            every = ticks_per(1.0 / node.config.explore.observation_rate, tick.period)
            if tick.due(every) and node.exchange.publish_observations(joined_up=True):
                self.evidence_stamp = now
            if self.evidence_stamp is not None:
                extra[EVIDENCE_KEY] = self.evidence_stamp
        node.publish_state(now, conv.ns_time_msg(tick.stamp), extra)
        return command
