"""The world node as a real process, checked over DDS from a plain rclpy client."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO
from rosutil import NodeProcess, RosClient, domain_id, ros_env

rclpy = pytest.importorskip("rclpy")
from coverage_msgs.msg import WorldStatus  # noqa: E402
from geometry_msgs.msg import Twist  # noqa: E402
from nav_msgs.msg import OccupancyGrid, Odometry  # noqa: E402
from rclpy.qos import qos_profile_sensor_data  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import LaserScan  # noqa: E402
from std_msgs.msg import Int32, String  # noqa: E402

from coverage_ros.core.world import load_world  # noqa: E402
from coverage_ros.nodes import conversions as conv  # noqa: E402
from coverage_ros.nodes.world_node import MAP_QOS  # noqa: E402

ROOM = """\
name: room
resolution: 0.05
bounds: [0, 0, 10, 10]
obstacles:
  - {type: box, center: [8, 2], size: [1, 1]}
robots:
  - [2.0, 2.0, 0.0]
  - [5.0, 5.0, 1.0]
"""


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    path = tmp_path_factory.mktemp("worlds") / "room.yaml"
    path.write_text(ROOM)
    return path


@pytest.fixture(scope="module")
def world(room):
    """One world node for the module (starting processes is the slow part), and a client."""
    domain = domain_id(0)
    with NodeProcess.world_node(domain, f"world:={room}", "real_time_factor:=2.0", "seed:=3",
                                "status_rate_hz:=5.0") as proc:
        client = RosClient(domain)
        try:
            yield proc, client
        finally:
            client.close()
        assert proc.alive(), proc.output()
        proc.signal(signal.SIGTERM)  # a clean shutdown on SIGTERM, exit code 0
        assert proc.proc.wait(timeout=10) == 0, proc.output()
        assert "Traceback" not in proc.output()


def statuses(msg: WorldStatus) -> dict[int, dict[str, float]]:
    return conv.world_status_robots(msg)


def test_clock_advances(world):
    _, client = world
    first = client.wait_for("/clock", Clock, timeout=15.0)
    t0 = conv.from_time_msg(first.clock)
    later = client.wait_for("/clock", Clock, lambda m: conv.from_time_msg(m.clock) > t0 + 0.5)
    assert conv.from_time_msg(later.clock) > t0


def test_map_reaches_a_late_subscriber(world, room):
    _, client = world
    client.wait_for("/clock", Clock, timeout=15.0)  # the node is up and has published /map
    msg = client.wait_for("/map", OccupancyGrid, qos=MAP_QOS, timeout=30.0)
    assert msg.header.frame_id == "map"
    grid = conv.occupancy_grid_to_grid(msg)
    expected = load_world(room).grid
    assert grid.shape == expected.shape and grid.origin == pytest.approx(expected.origin)
    np.testing.assert_array_equal(grid.occupancy, expected.occupancy)


def test_scan_has_all_beams_and_inf_where_nothing_is_hit(world):
    _, client = world
    msg = client.wait_for("/robot_0/scan", LaserScan, qos=qos_profile_sensor_data, timeout=15.0)
    assert msg.header.frame_id == "robot_0/base_scan"
    angles, ranges = conv.laser_scan_to_ranges(msg)
    assert len(ranges) == 360 and msg.range_max == pytest.approx(3.5)
    assert np.isposinf(ranges).sum() > 50  # the far walls are > 3.5 m away
    # Robot 0 stands still at (2, 2) facing +x (no test drives it): the beam pointing backwards
    # hits the wall x = 0 at 2 m; ahead, the box at x = 7.5 is beyond range.
    back = int(np.argmin(np.abs(np.abs(angles) - math.pi)))
    ahead = int(np.argmin(np.abs(angles)))
    assert ranges[back] == pytest.approx(2.0, abs=1e-4)
    assert np.isposinf(ranges[ahead])


def test_odom_follows_a_twist_command(world):
    _, client = world
    start = client.wait_for("/robot_1/odom", Odometry, timeout=15.0)
    assert start.header.frame_id == "robot_1/odom"
    assert start.child_frame_id == "robot_1/base_link"
    truth0 = client.wait_for("/robot_1/ground_truth", Odometry)
    assert truth0.header.frame_id == "map"
    x0, y0, _ = conv.odometry_to_pose(start)
    cmd = client.publisher("/robot_1/cmd_vel", Twist)
    odoms = client.subscribe("/robot_1/odom", Odometry)

    def driven() -> bool:
        cmd.publish(conv.command_to_twist(0.2, 0.0))
        return bool(odoms) and conv.odometry_to_pose(odoms[-1])[0] > x0 + 0.3

    client.spin_until(driven, timeout=30.0, what="robot_1 to drive 0.3 m forward")
    _, y, yaw = conv.odometry_to_pose(odoms[-1])
    assert abs(y - y0) < 0.02 and abs(yaw) < 0.02  # straight ahead in the odom frame
    # (at the commanded speed: the last odometry may already show the brake of a command
    # that came later than cmd_timeout, on a loaded machine)
    assert max(o.twist.twist.linear.x for o in odoms[-10:]) == pytest.approx(0.2, abs=0.01)
    truth = client.wait_for("/robot_1/ground_truth", Odometry)
    tx, ty, tyaw = conv.odometry_to_pose(truth)
    assert tyaw == pytest.approx(1.0, abs=0.02)  # the start heading in the map frame
    moved = math.hypot(tx - 5.0, ty - 5.0)
    assert moved > 0.3 and math.atan2(ty - 5.0, tx - 5.0) == pytest.approx(1.0, abs=0.05)


def test_nan_twist_is_dropped_without_a_crash(world):
    proc, client = world
    cmd = client.publisher("/robot_0/cmd_vel", Twist)
    bad = Twist()
    bad.linear.x = math.nan
    bad.angular.z = math.inf
    client.wait_for("/clock", Clock, timeout=15.0)
    for _ in range(5):
        cmd.publish(bad)
        client.spin_for(0.05)
    t = conv.from_time_msg(client.wait_for("/clock", Clock).clock)
    client.wait_for("/clock", Clock, lambda m: conv.from_time_msg(m.clock) > t + 0.2)
    odom = client.wait_for("/robot_0/odom", Odometry)
    assert all(math.isfinite(v) for v in conv.odometry_to_pose(odom))
    assert proc.alive()
    client.spin_until(lambda: "dropped cmd_vel" in proc.output(), 5.0, "the warning")


def test_robots_are_added_and_removed_at_run_time(world):
    proc, client = world
    spawn = client.publisher("/world/spawn", String)
    remove = client.publisher("/world/remove", Int32)
    client.spin_until(lambda: spawn.get_subscription_count() > 0, 15.0, "the spawn subscriber")
    spawn.publish(String(data="{id: 7, pose: [7.0, 7.0, 0.5], radius: 0.15}"))
    spawn.publish(String(data="{id: 8, pose: oops}"))  # malformed: dropped with a warning
    odom = client.wait_for("/robot_7/ground_truth", Odometry, timeout=10.0)
    assert conv.odometry_to_pose(odom) == pytest.approx((7.0, 7.0, 0.5), abs=1e-3)
    status = client.wait_for("/world/robots", WorldStatus, lambda m: 7 in statuses(m))
    assert statuses(status)[7]["radius"] == 0.15 and statuses(status)[7]["x"] == 7.0
    assert 8 not in statuses(status)
    remove.publish(Int32(data=7))
    client.wait_for("/world/robots", WorldStatus, lambda m: 7 not in statuses(m), timeout=10.0)
    # A spawn without id or pose gets the smallest free id and a free place.
    spawn.publish(String(data=""))
    status = client.wait_for("/world/robots", WorldStatus, lambda m: 2 in statuses(m),
                             timeout=10.0)
    assert len(status.robots) == 3 and status.world == "room"
    assert "dropped /world/spawn" in proc.output()


def test_ros2_run_layout_finds_and_runs_the_node():
    prefix = REPO / "install" / "coverage_ros"
    exe = prefix / "lib" / "coverage_ros" / "world_node"
    if not exe.exists():
        pytest.skip("no colcon layout: run scripts/test (it builds install/)")
    assert os.access(exe, os.X_OK)
    code = ("from ament_index_python.packages import get_package_prefix;"
            " print(get_package_prefix('coverage_ros'))")
    env = ros_env(domain_id(2), AMENT_PREFIX_PATH=str(prefix))
    found = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert found.stdout.strip() == str(prefix), found.stderr
    domain = domain_id(2)
    with NodeProcess.world_node(domain, "world:=office", "num_robots:=3",
                                "real_time_factor:=0.0", exe=str(exe)) as proc:
        client = RosClient(domain)
        try:
            msg = client.wait_for("/clock", Clock, lambda m: m.clock.sec >= 1, timeout=15.0)
            assert msg.clock.sec >= 1
            client.wait_for("/robot_2/odom", Odometry, timeout=30.0)
        finally:
            client.close()
        proc.signal(signal.SIGINT)  # clean shutdown, exit code 0
        assert proc.proc.wait(timeout=10) == 0, proc.output()
