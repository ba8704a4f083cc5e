"""Where a robot node's goals go: ``goal_pose`` for the viewers every coverage update, and with
``drive: false`` the robot's own navigator on ``goal_topic``, only when the goal moved
(:class:`~coverage_ros.core.control.goal_relay.GoalRelay`); the last goal sent goes out again
when a subscriber appeared since: a navigator started after the robot node (or restarted) has
not seen it, and a robot whose goal no longer moves would otherwise wait for ever."""

from __future__ import annotations

from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped

from coverage_ros.core.control.goal_relay import GoalRelay
from coverage_ros.nodes import conversions as conv


class GoalOutput:
    def __init__(self, publisher, drive: bool, goal_topic: str, resend_distance: float) -> None:
        """``publisher(msg_type, topic)`` creates the node's publishers."""
        self.shown = publisher(PoseStamped, "goal_pose")
        self.relay = None if drive else GoalRelay(resend_distance)
        self.navigator: Any = None  # (a publisher with drive: false)
        self._listening = 0  # subscriptions to the navigator's topic at the last goal
        if not drive:
            self.navigator = self.shown if goal_topic == "goal_pose" else \
                publisher(PoseStamped, goal_topic)

    def publish(self, stamp: Time, goal: np.ndarray | None, pose: np.ndarray) -> None:
        """The strategy's goal (None: none this update) seen from the robot's ``pose``."""
        if self.relay is not None:
            # An external navigator replans on every goal: send only those that moved, and the
            # last one again to a navigator that subscribed since (module docstring).
            listening = self.navigator.get_subscription_count()
            if listening > self._listening and self.relay.sent is not None:
                self.navigator.publish(conv.pose_stamped_msg(stamp, *self.relay.sent))
            self._listening = listening
            sent = None if goal is None else self.relay.offer(goal, pose)
            if sent is not None:
                self.navigator.publish(conv.pose_stamped_msg(stamp, *sent))
            if self.navigator is self.shown:
                return
        if goal is not None:
            self.shown.publish(conv.pose_stamped_msg(stamp, goal[0], goal[1], float(pose[2])))

    def hold(self, stamp: Time, pose: np.ndarray | None, paused: bool) -> None:
        """Pausing (``paused``) or resuming: a navigator keeps its last goal, so it gets the
        robot's own pose to hold at, and the coverage goal is sent afresh on resume."""
        if self.relay is None or pose is None:
            return
        self.relay.reset()
        if paused:
            self.navigator.publish(conv.pose_stamped_msg(stamp, float(pose[0]), float(pose[1]),
                                                         float(pose[2])))
