"""Bad input everywhere: hypothesis-generated malformed messages on every topic the team's nodes
subscribe to (NaN and infinities, empty and huge arrays, torn grids, wrong frames, unknown robot
ids, out-of-order and impossible stamps), sent to the real nodes as processes over DDS
(``coverage_ros/bench/fuzz.py``; ``scripts/bench_faults --only fuzz`` sends more)."""

from __future__ import annotations

import pytest
from rosutil import domain_id

from coverage_ros.bench.fuzz import ROBOTS, FuzzReport, FuzzTeam
from coverage_ros.bench.fuzz_messages import TOPICS

pytestmark = pytest.mark.slow


def test_the_table_names_every_subscribed_topic_of_every_node():
    """Every node kind is fuzzed, and each on the inputs it has (the live test checks that
    each topic really has that many subscribers before sending anything)."""
    listeners = {n for t in TOPICS for n in t.nodes}
    assert listeners == {"world", "bridge", "markers"} | {f"robot_{r}" for r in ROBOTS}
    assert {t.topic for t in TOPICS if "world" in t.nodes} >= {
        "/robot_0/cmd_vel", "/world/spawn", "/world/remove"}
    assert {t.topic for t in TOPICS if "robot_1" in t.nodes} >= {"/tf", "/tf_static", "/map"}
    assert any("/robot_77/" in t.topic for t in TOPICS)  # a robot nobody runs


def test_every_node_survives_malformed_messages_and_keeps_its_last_good_state(tmp_path):
    report = FuzzReport()
    with FuzzTeam(tmp_path / "fuzz", domain_id(29)) as team:
        team.wait_ready()
        team.fuzz(15, report)
        sim = team.sim_time()
        team.check(report)
        team.stop_bridge_and_read(report, sim)
    print(report.as_json())
    assert report.node_crashes == 0
    assert report.problems == [], "\n".join(report.problems)
    assert report.messages >= 15 * len(TOPICS) - 20  # a few strategies have fewer distinct ones
    # Something was dropped everywhere, and said so - once per kind of problem, not per message.
    assert all(0 < n <= 30 for n in report.warnings.values()), report.warnings


def test_a_transform_with_an_impossible_stamp_or_rotation_is_dropped():
    """Found by the fuzzer: a transform stamped with nanosec >= 1e9 (a time in the future) or a
    zero quaternion was taken, and robot 1 (pose from /tf) drove on a pose that was not its."""
    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import Quaternion, TransformStamped
    from tf2_msgs.msg import TFMessage

    from coverage_ros.nodes import conversions as conv

    good = conv.transform_msg(conv.to_time_msg(3.0), "map", "robot_1/odom", (1.0, 2.0, 0.5))
    future = conv.transform_msg(Time(sec=3, nanosec=4_000_000_000), "map", "robot_1/odom",
                                (5.0, 5.0, 0.0))
    zero = TransformStamped(header=good.header, child_frame_id="robot_1/odom")
    zero.transform.rotation = Quaternion(x=0.0, y=0.0, z=0.0, w=0.0)
    kept, dropped = conv.transforms_of(TFMessage(transforms=[good, future, zero]))
    assert [(p, c) for p, c, _, _ in kept] == [("map", "robot_1/odom")]
    assert kept[0][2] == pytest.approx((1.0, 2.0, 0.5)) and kept[0][3] == pytest.approx(3.0)
    assert "nanosec 4000000000" in dropped[0] and "not a unit quaternion" in dropped[1]
