"""Message <-> numpy conversions (no DDS needed, only the message packages)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("nav_msgs")
from geometry_msgs.msg import Twist

from coverage_ros.core.world import LidarSpec, RobotSpec
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError
from coverage_ros.nodes import conversions as conv


@pytest.mark.parametrize("yaw", [0.0, 0.5, -2.0, math.pi - 1e-6])
def test_yaw_quaternion_round_trip(yaw):
    assert conv.quaternion_to_yaw(conv.yaw_to_quaternion(yaw)) == pytest.approx(yaw)


def test_time_round_trip():
    msg = conv.to_time_msg(12.345678901)
    assert (msg.sec, msg.nanosec) == (12, 345678901)
    assert conv.from_time_msg(msg) == pytest.approx(12.345678901)


def test_grid_round_trip_keeps_cells_and_origin(rng):
    occ = rng.choice(np.array([-1, 0, 100], dtype=np.int8), size=(30, 40))
    grid = GridMap(occ, 0.05, (-1.0, 2.0, 0.3))
    msg = conv.grid_to_occupancy_grid(grid, conv.to_time_msg(1.0))
    assert (msg.info.width, msg.info.height) == (40, 30)
    back = conv.occupancy_grid_to_grid(msg)
    np.testing.assert_array_equal(back.occupancy, occ)
    assert back.origin == pytest.approx(grid.origin)


def test_laser_scan_keeps_rep117_values():
    lidar = LidarSpec(beams=4)
    ranges = np.array([1.0, np.inf, -np.inf, 3.25], dtype=np.float32)
    msg = conv.laser_scan_msg(ranges, lidar, conv.to_time_msg(0.2), "robot_0/base_scan")
    assert msg.angle_min == pytest.approx(-math.pi)
    assert msg.angle_max == pytest.approx(-math.pi + 3 * math.pi / 2)
    angles, back = conv.laser_scan_to_ranges(msg)
    np.testing.assert_array_equal(back, ranges)
    assert angles[2] == pytest.approx(0.0)


def test_odometry_message_fields():
    msg = conv.odometry_msg(conv.to_time_msg(1.0), "robot_1/odom", "robot_1/base_link",
                            (1.0, 2.0, 0.5), (0.2, 0.0, 0.1), (0.01, 0.002))
    assert conv.odometry_to_pose(msg) == pytest.approx((1.0, 2.0, 0.5))
    assert msg.pose.covariance[0] == msg.pose.covariance[7] == pytest.approx(0.01)
    assert msg.pose.covariance[35] == pytest.approx(0.002)


def test_twist_command_must_be_finite():
    assert conv.twist_to_command(conv.command_to_twist(0.2, -0.4)) == (0.2, -0.4)
    bad = Twist()
    bad.angular.z = math.nan
    with pytest.raises(ValueError, match="finite"):
        conv.twist_to_command(bad)


def test_frames():
    f = conv.RobotFrames.of("robot_", 3)
    assert f.topic("cmd_vel") == "/robot_3/cmd_vel"
    assert (f.odom, f.base_link, f.base_scan) == ("robot_3/odom", "robot_3/base_link",
                                                  "robot_3/base_scan")


def test_spawn_requests():
    base = RobotSpec()
    req = conv.parse_spawn_request("{id: 7, pose: [1, 2, 0.5], radius: 0.2}", base)
    assert req.robot_id == 7 and req.pose == (1.0, 2.0, 0.5) and req.robot.radius == 0.2
    req = conv.parse_spawn_request("", base)
    assert req.robot_id is None and req.pose is None and req.robot == base
    assert conv.parse_spawn_request("pose: [1, 2]", base).pose == (1.0, 2.0, 0.0)


@pytest.mark.parametrize("text, match", [
    ("{id: 7", "malformed YAML"),
    ("[1, 2]", "must be a YAML mapping"),
    ("{id: -1}", "spawn.id"),
    ("{id: 1.5}", "spawn.id"),
    ("{pose: [1, .nan]}", "spawn.pose"),
    ("{pose: oops}", "spawn.pose"),
    ("{colour: red}", "spawn.colour: unknown key"),
    ("{radius: -1}", "robot.radius"),
    ("{v_max: abc}", "spawn.v_max"),
])
def test_bad_spawn_requests_name_the_field(text, match):
    with pytest.raises(ConfigError, match=match):
        conv.parse_spawn_request(text, RobotSpec())


def test_evidence_round_trip_on_a_rotated_lattice(rng):
    from coverage_ros.core.exploration.belief import Evidence

    lattice = GridMap(np.full((20, 30), -1, np.int8), 0.05, (1.0, -2.0, 0.4))
    cells = rng.choice(600, size=50, replace=False)
    ev = Evidence(3, cells, rng.integers(0, 400, 50).astype(np.uint16),
                  rng.integers(0, 400, 50).astype(np.uint16))
    msg = conv.evidence_msg(ev, lattice, conv.to_time_msg(2.0))
    assert [f.name for f in msg.fields] == ["x", "y", "hits", "misses"]
    assert msg.width == 50 and msg.point_step == 12 and msg.header.frame_id == "map"
    back = conv.evidence_from_msg(msg, 3, lattice)
    np.testing.assert_array_equal(back.cells, cells)
    np.testing.assert_array_equal(back.hits, ev.hits)
    np.testing.assert_array_equal(back.misses, ev.misses)


def test_malformed_evidence_clouds_are_refused_with_the_reason():
    from coverage_ros.core.exploration.belief import Evidence

    lattice = GridMap(np.full((10, 10), -1, np.int8), 0.05)
    ok = conv.evidence_msg(Evidence(1, np.array([5, 6]), np.array([1, 2], np.uint16),
                                    np.array([0, 3], np.uint16)), lattice, conv.to_time_msg(0))
    wrong_frame = conv.evidence_msg(Evidence(1, np.array([5]), np.array([1], np.uint16),
                                             np.array([0], np.uint16)), lattice,
                                    conv.to_time_msg(0))
    wrong_frame.header.frame_id = "odom"
    with pytest.raises(ConfigError, match="frame_id"):
        conv.evidence_from_msg(wrong_frame, 1, lattice)
    torn = conv.evidence_msg(Evidence(1, np.array([5, 6]), np.array([1, 2], np.uint16),
                                      np.array([0, 3], np.uint16)), lattice, conv.to_time_msg(0))
    torn.width = 3
    with pytest.raises(ConfigError, match="size does not match"):
        conv.evidence_from_msg(torn, 1, lattice)
    small = GridMap(np.full((2, 2), -1, np.int8), 0.05)
    with pytest.raises(ConfigError, match="outside the map"):
        conv.evidence_from_msg(ok, 1, small)
    ok.fields = ok.fields[:2]
    with pytest.raises(ConfigError, match="fields"):
        conv.evidence_from_msg(ok, 1, lattice)


STATES = {
    # before the first update: presence (acvt: its first extras)
    "presence": {"x": 1.0, "y": 2.0, "weight": 0.0, "radius": 0.105, "v_max": 0.22},
    "acvt presence": {"x": 1.0, "y": 2.0, "weight": 0.0, "radius": 0.105, "v_max": 0.22,
                      "reach": 0.22, "dropout": 1.0, "iteration": 0.0, "greedy": 0.0,
                      "settled": 0.0, "relocating": 0.0},
    "geodesic": {"x": 1.0, "y": 2.0, "weight": 0.5, "mass": 3.5, "cost": 1.25,
                 "update_ms": 12.0, "radius": 0.105, "v_max": 0.22, "manual": 0.0,
                 "paused": 1.0, "mode": 0.0, "vx": 0.1, "vy": -0.2},
    "tangentbug": {"x": 1.0, "y": 2.0, "weight": 0.0, "mass": 3.5, "cost": 1.25,
                   "update_ms": 2.0, "radius": 0.105, "v_max": 0.22, "manual": 0.0,
                   "paused": 0.0, "mode": 11.0, "virtual_x": 1.5, "virtual_y": 2.5,
                   "cost_real": 1.25, "cost_virtual": 1.0, "converged": 1.0},
    "acvt with a plan": {"x": 1.0, "y": 2.0, "weight": 0.0, "mass": 3.5, "cost": 1.25,
                         "update_ms": 2.0, "radius": 0.105, "v_max": 0.4, "manual": 0.0,
                         "paused": 0.0, "mode": 17.0, "reach": 0.4, "dropout": 0.0,
                         "iteration": 42.0, "greedy": 1.0, "settled": 1.0, "relocating": 1.0,
                         "plan_from": 0.0, "plan_seq": 3.0, "plan_3_x": 5.0, "plan_3_y": 6.0,
                         "plan_12_x": 7.0, "plan_12_y": 8.0},
    "exploring, lock-step": {"x": 1.0, "y": 2.0, "weight": 0.0, "mass": 3.5, "cost": 1.25,
                             "update_ms": 2.0, "radius": 0.105, "v_max": 0.22,
                             "manual": 1.0, "paused": 0.0, "mode": -1.0, "greedy": 1.0,
                             "evidence_stamp": 12.3},
    "geodesic, closet escape": {"x": 1.0, "y": 2.0, "weight": 0.0, "mass": 3.5, "cost": 1.25,
                                "update_ms": 2.0, "radius": 0.105, "v_max": 0.22,
                                "manual": 0.0, "paused": 0.0, "mode": 17.0, "settled": 1.0,
                                "offer_gain": 0.5, "offer_x": 3.0, "offer_y": 4.0,
                                "offer_base": 2.0, "offer2_gain": 0.375, "offer2_x": -1.0,
                                "offer2_y": 6.5, "claim": 4.0, "claim_gain": 0.25,
                                "grant": -1.0, "relocating": 1.0, "to_x": 5.5, "to_y": -0.5},
    "another package's strategy": {"x": 1.0, "y": 2.0, "weight": 0.0, "radius": 0.105,
                                   "v_max": 0.22, "my_value": 4.5},
}


@pytest.mark.parametrize("name", sorted(STATES))
def test_a_coverage_state_keeps_every_value_it_had(name):
    """What a robot publishes is what its neighbours' tables get back, value for value, with
    every strategy's values in their typed fields."""
    values = STATES[name]
    msg = conv.coverage_state_msg(conv.to_time_msg(5.0), values, robot_id=7)
    assert msg.robot_id == 7 and msg.header.frame_id == "map"
    assert conv.coverage_state_values(msg) == pytest.approx(values)
    assert (len(msg.acvt), len(msg.tangentbug), len(msg.explore), len(msg.handover)) == {
        "acvt presence": (1, 0, 0, 0), "acvt with a plan": (1, 0, 0, 0),
        "tangentbug": (0, 1, 0, 0), "exploring, lock-step": (0, 0, 1, 0),
        "geodesic, closet escape": (0, 0, 0, 1)}.get(name, (0, 0, 0, 0))
    assert list(msg.extra_names) == (["my_value"] if "another" in name else [])


def test_a_malformed_coverage_state_is_refused_with_the_reason():
    from coverage_msgs.msg import RobotState

    for change, reason in ((lambda m: setattr(m.header, "frame_id", "odom"), "frame_id"),
                           (lambda m: setattr(m, "x", math.nan), "not finite"),
                           (lambda m: setattr(m, "extra_names", ["a"]), "extra names"),
                           (lambda m: setattr(m.acvt[0], "plan_x", [1.0]), "acvt plan")):
        msg = conv.coverage_state_msg(conv.to_time_msg(1.0), STATES["acvt with a plan"])
        assert isinstance(msg, RobotState)
        change(msg)
        with pytest.raises(ValueError, match=reason):
            conv.coverage_state_values(msg)


def test_the_world_status_carries_every_robot_field():
    robot = {"id": 3, "x": 1.0, "y": 2.0, "yaw": 0.5, "driving": True, "collisions": 2,
             "robot_collisions": 1, "wall_collisions": 1, "path_length": 4.5, "scans": 10,
             "spawn_time": 0.0, "min_separation": math.inf, "radius": 0.105, "v_max": 0.22,
             "w_max": 2.84, "a_max": 2.5, "alpha_max": 3.2, "sensor_radius": 3.5,
             "power_weight": 0.0, "lidar_range_max": 3.5}
    msg = conv.world_status_msg(conv.to_time_msg(2.0), "office", 1.0, 100, 0, [robot])
    assert conv.world_status_robots(msg) == {3: pytest.approx({k: float(v)
                                                               for k, v in robot.items()})}


def test_scan_hits_are_placed_with_the_robot_pose():
    pytest.importorskip("sensor_msgs")
    from coverage_ros.core.world import LidarSpec
    from coverage_ros.nodes import conversions as conv

    lidar = LidarSpec(beams=4, range_min=0.12, range_max=3.5)  # beams at -pi, -pi/2, 0, pi/2
    msg = conv.laser_scan_msg(np.array([1.0, np.inf, 2.0, 0.05]), lidar, conv.to_time_msg(1.0),
                              "robot_0/base_scan")
    angles, _ = conv.laser_scan_to_ranges(msg)
    np.testing.assert_allclose(angles, [-math.pi, -math.pi / 2, 0.0, math.pi / 2], atol=1e-6)
    # Robot at (2, 1) facing +y: the beam ahead (2 m) hits (2, 3), the one behind (1 m) hits
    # (2, 0); no return (+inf) and a range below range_min give no point.
    points = conv.scan_to_points(msg, (2.0, 1.0, math.pi / 2))
    np.testing.assert_allclose(points, [[2.0, 0.0], [2.0, 3.0]], atol=1e-6)
