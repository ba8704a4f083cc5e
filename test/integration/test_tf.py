"""/tf like a real robot's: the world node's REP 105 chain per robot, consistent with its
ground truth (the frame math: unit/core/control/test_frames.py; tf2_msgs' type hash:
unit/nodes/test_messages.py)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from rosutil import NodeProcess, RosClient, domain_id

from coverage_ros.core.control.frames import FrameTree


def test_the_world_publishes_each_robots_chain_consistent_with_ground_truth():
    """Two robots driving with odometry noise: for each, map -> odom -> base_link composed
    equals its ground truth at the same stamp, odom -> base_link is its odometry, and the
    drift shows up in map -> odom; base_link -> base_scan is static."""
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry
    from tf2_msgs.msg import TFMessage

    from coverage_ros.nodes import conversions as conv
    from coverage_ros.nodes.tf_input import TF_STATIC_QOS

    domain = domain_id(9)
    with NodeProcess.world_node(domain, "world:=empty", "num_robots:=2", "seed:=4",
                                "odom_noise_trans:=0.05", "odom_noise_rot:=0.05") as world:
        client = RosClient(domain)
        try:
            tfs = client.subscribe("/tf", TFMessage, 100)
            static = client.subscribe("/tf_static", TFMessage, TF_STATIC_QOS)
            truth = {i: client.subscribe(f"/robot_{i}/ground_truth", Odometry) for i in (0, 1)}
            cmd = {i: client.node.create_publisher(Twist, f"/robot_{i}/cmd_vel", 10)
                   for i in (0, 1)}
            drive = Twist()
            drive.linear.x, drive.angular.z = 0.2, 0.4
            # The world is up and listens before the drive (a slow start ate the commands).
            client.spin_until(lambda: all(truth.values())
                              and all(p.get_subscription_count() > 0 for p in cmd.values()),
                              60, "the world's ground truth and cmd_vel subscriptions")
            start = {i: conv.odometry_to_pose(truth[i][-1])[:2] for i in (0, 1)}

            def driven(i: int) -> float:
                return float(np.hypot(*(np.subtract(conv.odometry_to_pose(truth[i][-1])[:2],
                                                    start[i]))))

            deadline = time.monotonic() + 60.0
            while min(driven(i) for i in (0, 1)) < 0.3 and time.monotonic() < deadline:
                for pub in cmd.values():
                    pub.publish(drive)
                client.spin_for(0.1)
            assert min(driven(i) for i in (0, 1)) >= 0.3, "the robots did not drive 0.3 m"
            client.spin_until(lambda: static, 10, "tf_static")
        finally:
            client.close()
        assert world.alive()
    statics = {(p, c) for m in static for p, c, _, _ in conv.transforms_of(m)[0]}
    assert statics == {(f"robot_{i}/base_link", f"robot_{i}/base_scan") for i in (0, 1)}
    by_stamp: dict = {}
    for m in tfs:
        for parent, child, pose, stamp in conv.transforms_of(m)[0]:
            by_stamp.setdefault(stamp, FrameTree()).set(parent, child, pose, stamp)
    checked, drift = 0, 0.0
    for i in (0, 1):
        for msg in truth[i][-20:]:
            t = conv.from_time_msg(msg.header.stamp)
            tree = by_stamp.get(t)
            if tree is None:
                continue
            chain, _ = tree.lookup("map", f"robot_{i}/base_link")
            want = conv.odometry_to_pose(msg)
            assert chain[:2] == pytest.approx(want[:2], abs=1e-6)
            assert math.cos(chain[2] - want[2]) == pytest.approx(1.0, abs=1e-9)
            drift = max(drift, float(np.hypot(*tree.links[f"robot_{i}/odom"].pose[:2])))
            checked += 1
    assert checked >= 10
    assert drift > 1e-4  # the odometry noise is in map -> odom
