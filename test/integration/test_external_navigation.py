"""drive: false - the robot publishes its coverage goal for its own navigator (Nav2) and no
cmd_vel: the relay's rules, the parameter checks, and a live team driven by a stand-in
navigator process."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from conftest import REPO
from rosutil import NodeProcess, domain_id
from teamdiag import team_diagnosis

from coverage_ros.core.control.goal_relay import GoalRelay
from coverage_ros.errors import ConfigError
from coverage_ros.nodes.robot_config import PARAMETERS, load_robot_inputs


def test_goals_are_sent_again_only_when_they_moved():
    relay = GoalRelay(resend_distance=0.25)
    pose = np.array([0.0, 0.0, 0.0])
    first = relay.offer(np.array([1.0, 1.0]), pose)
    assert first is not None and first[2] == pytest.approx(math.pi / 4)  # heading of the way
    assert relay.offer(np.array([1.1, 1.1]), pose) is None  # 0.14 m: the navigator keeps it
    assert relay.offer(np.array([1.0, 1.24]), pose) is None
    moved = relay.offer(np.array([1.0, 1.3]), pose)  # 0.3 m from the goal sent: sent
    assert moved is not None and moved[:2] == pytest.approx([1.0, 1.3])
    assert relay.offer(np.array([1.0, 1.1]), pose) is None  # measured from the last one sent
    assert relay.offer(np.array([np.nan, 1.0]), pose) is None
    # At the goal already: the robot's own heading (no turn on the spot).
    here = GoalRelay(0.25).offer(np.array([2.0, 0.0]), np.array([2.0, 0.0, 1.0]))
    assert here[2] == pytest.approx(1.0)
    relay.reset()
    assert relay.offer(np.array([1.0, 1.3]), pose) is not None and relay.count == 3


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


@pytest.mark.integration
@pytest.mark.slow
def test_a_team_with_its_own_navigation_and_localization_converges(tmp_path):
    """Three robots set up as on a Nav2 robot: drive: false, driven by a stand-in navigator
    that only sees their goal_pose topics, and pose_source: tf (the pose from /tf, as AMCL
    gives it). No robot node publishes cmd_vel, each goal differs from the previous one by more
    than the resend distance, and the team spreads as one that drives itself does."""
    domain = domain_id(3)
    result = tmp_path / "nav.json"
    nav = NodeProcess([sys.executable, str(REPO / "test" / "nav_stub.py"), str(result),
                       "0", "1", "2"], domain)
    with nav:
        out = tmp_path / "team"
        # At twice real time: three robots and the navigator keep up on two cores.
        proc = subprocess.run(
            [str(REPO / ".venv" / "bin" / "coverage-team"), "--quiet", "--world", "empty",
             "--robots", "3", "--duration", "45", "--seed", "2", "--rtf", "2", "--out", str(out),
             "--domain-id", str(domain), "--robot-param", "drive:=false",
             "--robot-param", "pose_source:=tf"],
            capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert nav.stop() == 0, nav.output()[-2000:]
    got = json.loads(result.read_text())
    summary = json.loads((out / "summary.json").read_text())
    m = summary["metrics"]
    assert m["H"] <= 0.5 * m["H_start"], team_diagnosis(summary, out)
    for rid in ("0", "1", "2"):
        assert got["cmd_vel_publishers"][rid] == [], got["cmd_vel_publishers"]
        goals = np.array([g[1:4] for g in got["goals"][rid]])
        assert len(goals) >= 2, got["goals"][rid]
        assert all(g[4] == "map" for g in got["goals"][rid])
        steps = np.hypot(*np.diff(goals[:, :2], axis=0).T)
        # moved by more than the resend distance, or the last goal again for a subscriber that
        # appeared on goal_pose since (the bridge, the markers or this navigator)
        assert ((steps > 0.25) | (steps == 0.0)).all() and (steps > 0.25).any(), steps
        # Its coverage_state carries the velocity its navigator drives it at (from its
        # poses): the stub drives at 0.18 m/s at most.
        assert 0.05 < got["state_speed"][rid] < 0.3, got["state_speed"]
    for r in summary["robots"]:
        assert r["path_length"] > 0.3, r
        log = (out / "logs" / f"robot_{r['id']}.log").read_text()
        assert f"pose from /tf (map -> robot_{r['id']}/base_link)" in log, log[-2000:]
