"""drive: false on the robot node: the goal output for the robot's own navigator (Nav2) and the
parameter checks (coverage_ros/nodes/goal_output.py, robot_config.py)."""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time

from coverage_ros.errors import ConfigError
from coverage_ros.nodes.robot_config import load_robot_inputs
from coverage_ros.nodes.robot_parameters import PARAMETERS


def values(**over):
    v = {name: default for name, (default, _) in PARAMETERS.items()}
    v.update(world="empty", robot_id=0)
    v.update(over)
    return v


def test_a_navigator_that_subscribes_late_gets_the_current_goal():
    """A goal sent before the navigator matched is lost; when a subscription appears, the
    last goal sent goes out again (once), and a navigator leaving sends nothing."""
    from coverage_ros.nodes.goal_output import GoalOutput

    class Topic:
        def __init__(self) -> None:
            self.sent: list = []
            self.subscribers = 0

        def publish(self, msg) -> None:
            self.sent.append((msg.pose.position.x, msg.pose.position.y))

        def get_subscription_count(self) -> int:
            return self.subscribers

    topics: dict[str, Topic] = {}
    out = GoalOutput(lambda _type, name: topics.setdefault(name, Topic()), drive=False,
                     goal_topic="navigate/goal", resend_distance=0.25)
    nav, stamp, pose, goal = topics["navigate/goal"], Time(), np.zeros(3), np.array([2.0, 1.0])
    out.publish(stamp, goal, pose)  # nobody listens yet: sent, and lost
    out.publish(stamp, goal, pose)
    assert nav.sent == [(2.0, 1.0)]
    nav.subscribers = 1  # the navigator comes up
    out.publish(stamp, goal, pose)
    out.publish(stamp, goal + 0.1, pose)  # creeps: not again
    assert nav.sent == [(2.0, 1.0), (2.0, 1.0)]
    nav.subscribers = 0  # it goes away, then restarts
    out.publish(stamp, goal, pose)
    nav.subscribers = 1
    out.publish(stamp, goal, pose)
    assert nav.sent == [(2.0, 1.0)] * 3
    assert len(topics["goal_pose"].sent) == 6  # the viewers' topic: every update


def test_drive_false_is_checked_with_the_rest_of_the_parameters():
    cfg = load_robot_inputs(values(drive=False), "/robot_0").config
    assert not cfg.drive and cfg.goal_topic == "goal_pose" and cfg.goal_resend_distance == 0.25
    with pytest.raises(ConfigError, match="drive"):
        load_robot_inputs(values(drive=False, manual=True), "/robot_0")
    with pytest.raises(ConfigError, match="goal_topic"):
        load_robot_inputs(values(drive=False, goal_topic=""), "/robot_0")
    with pytest.raises(ConfigError, match="goal_resend_distance"):
        load_robot_inputs(values(goal_resend_distance=-1.0), "/robot_0")
