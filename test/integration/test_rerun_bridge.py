"""The rerun bridge: its numpy helpers and layers without ROS, then the real node streaming a
world node's team (plus messages a test client publishes as the robots) into a .rrd file."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
from dataclasses import dataclass, field

import numpy as np
import pytest
from conftest import REPO
from rosutil import NodeProcess, RosClient, domain_id
from rrdutil import read_rrd

from coverage_ros.core.control.pose_history import PoseHistory
from coverage_ros.core.world.grid import GridMap
from coverage_ros.viz.colors import robot_color
from coverage_ros.viz.team import Schedule, Trajectory, compose_cell_labels

RERUN = REPO / ".venv" / "bin" / "rerun"


# ---------------------------------------------------------------------------- reading a recording
def cell_rgba(row: dict) -> np.ndarray:
    """``(H, W, 4)`` cell layer of a /world/cells row, flipped back to ROS row order."""
    fmt = row["GridMap:format"][0]
    data = np.array(row["GridMap:data"][0], dtype=np.uint8)
    return np.flipud(data.reshape(fmt["height"], fmt["width"], 4))


def rerun_verify(path) -> subprocess.CompletedProcess:
    exe = str(RERUN) if RERUN.exists() else "rerun"
    return subprocess.run([exe, "rrd", "verify", str(path)], capture_output=True, text=True,
                          timeout=60)


# ---------------------------------------------------------------------------- unit tests
def test_compose_cell_labels_places_crops_and_later_cells_win():
    grid = GridMap(np.zeros((10, 12)), 0.5, (-1.0, 2.0, 0.0))
    a = GridMap(np.full((4, 3), 100), 0.5, (0.0, 3.0, 0.0))  # rows 2..5, cols 2..4
    b_occ = np.zeros((2, 4))
    b_occ[:, 1:] = 100  # first column not in the cell
    b = GridMap(b_occ, 0.5, (0.5, 4.5, 0.0))  # rows 5..6, cols 3..6, overlaps a at (5, 4)
    off = GridMap(np.full((3, 3), 100), 0.5, (40.0, 40.0, 0.0))  # beyond the map
    edge = GridMap(np.full((3, 3), 100), 0.5, (4.0, 6.0, 0.0))  # rows 8..10, cols 10..12
    labels = compose_cell_labels(grid, [a, b, off, edge])
    expected = np.full((10, 12), -1)
    expected[2:6, 2:5] = 0
    expected[5:7, 4:7] = 1
    expected[8:10, 10:12] = 3
    np.testing.assert_array_equal(labels, expected)
    assert compose_cell_labels(grid, []).max() == -1


def test_compose_cell_labels_resamples_a_rotated_coarser_cell():
    grid = GridMap(np.zeros((40, 40)), 0.1)
    cell = GridMap(np.full((2, 2), 100), 0.5, (2.0, 1.0, math.pi / 4))  # a 1 m square at 45 deg
    labels = compose_cell_labels(grid, [cell])
    X, Y = grid.all_cell_centers()
    u = (X - 2.0) * math.cos(math.pi / 4) + (Y - 1.0) * math.sin(math.pi / 4)
    v = -(X - 2.0) * math.sin(math.pi / 4) + (Y - 1.0) * math.cos(math.pi / 4)
    inside = (u >= 0) & (u < 1.0) & (v >= 0) & (v < 1.0)
    np.testing.assert_array_equal(labels == 0, inside)
    assert inside.sum() == pytest.approx(100, rel=0.1)  # 1 m^2 of 0.01 m^2 cells


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


def test_pose_history_interpolates_along_the_short_way():
    h = PoseHistory()
    assert h.at(1.0) is None and h.latest is None
    h.add(1.0, (0.0, 0.0, 3.0))
    h.add(2.0, (1.0, 2.0, -3.0))  # 0.28 rad counter-clockwise across +-pi
    x, y, yaw = h.at(1.5)
    assert (x, y) == pytest.approx((0.5, 1.0))
    assert abs(math.remainder(yaw - math.pi, 2 * math.pi)) < 1e-9
    assert h.at(2.3) == h.latest == (1.0, 2.0, -3.0)  # just after: the nearest sample
    assert h.at(5.0) is None  # too far from any sample
    h.add(1.5, (9.0, 9.0, 0.0))  # out of order: ignored
    assert h.at(1.5)[0] == pytest.approx(0.5)


def test_pose_history_velocity_is_the_mean_over_its_window():
    h = PoseHistory()
    assert h.velocity() == {}
    h.add(0.0, (1.0, 1.0, 0.0))
    h.add(0.01, (1.003, 1.004, 0.0))
    assert h.velocity() == {}  # two samples 10 ms apart: too short a span
    h = PoseHistory()
    for k in range(21):  # 1 s at 20 Hz, 0.5 m/s along (0.6, 0.8), then 0.5 s standing
        t = 0.05 * k
        h.add(t, (1.0 + 0.3 * t, 1.0 + 0.4 * t, 0.9))
    v = h.velocity()
    assert (v["vx"], v["vy"]) == pytest.approx((0.3, 0.4))
    for k in range(1, 11):
        h.add(1.0 + 0.05 * k, (1.3, 1.4, 0.9))
    assert (h.velocity()["vx"], h.velocity()["vy"]) == pytest.approx((0.0, 0.0))
    # 0.1 s into the stop, the mean over the last 0.3 s: 0.2 s of motion in it
    h = PoseHistory()
    for k in range(21):
        h.add(0.05 * k, (0.3 * 0.05 * k, 0.0, 0.0))
    h.add(1.1, (0.3, 0.0, 0.0))
    assert h.velocity()["vx"] == pytest.approx(0.3 * (1.0 - 0.8) / 0.3)


def test_trajectory_pieces_join_without_gaps_and_stay_small():
    traj = Trajectory(segment_points=5)
    pts = np.column_stack([np.arange(14) * 0.1, np.zeros(14)])
    for x, y in pts:
        assert traj.add(x, y)
    assert not traj.add(1.3 + 1e-4, 0.0)  # a robot at rest adds nothing
    pieces = traj.take_finished()
    assert [k for k, _ in pieces] == [0, 1, 2] and traj.take_finished() == []
    assert all(len(p) == 5 for _, p in pieces)
    joined = np.vstack([pieces[0][1]] + [p[1:] for _, p in pieces[1:]] + [traj.tail[1:]])
    np.testing.assert_allclose(joined, pts)
    traj.break_path()
    assert [k for k, _ in traj.take_finished()] == [3] and len(traj.tail) == 0


def test_schedule_runs_once_per_period_and_restarts_when_time_goes_back():
    s = Schedule(0.5)
    assert [s.due(t) for t in (0.0, 0.2, 0.5, 0.6, 1.0, 3.0, 3.1)] == \
        [True, False, True, False, True, True, False]
    assert s.due(0.1)  # the simulation was restarted
    always = Schedule(0.0)
    assert all(always.due(t) for t in (1.0, 1.0, 1.1))


def test_live_team_layers_without_ros(tmp_path):
    """LiveTeam -> .rrd: markers, trajectory, cells in the robots' colours, metrics."""
    from coverage_ros.viz.live_metrics import LiveMetrics
    from coverage_ros.viz.live_team import LiveRates, LiveTeam
    from coverage_ros.viz.recording import CoverageRecorder

    occ = np.zeros((40, 60), dtype=np.int8)
    occ[:, 30] = 100  # a wall with a door
    occ[18:22, 30] = 0
    grid = GridMap(occ, 0.1)
    warnings = []
    rec = CoverageRecorder("unit-test")
    rec.set_outputs(tmp_path / "team.rrd")
    metrics = LiveMetrics(rec, 0.1, None, lambda key, text: warnings.append(text))
    team = LiveTeam(rec, LiveRates(metrics_period=0.5, cells_period=0.0), metrics)
    team.set_map(grid)
    team.add_robot(3)
    team.add_robot(7)
    for k in range(21):
        t = 0.1 * k
        team.pose(3, t, (1.0 + 0.1 * k, 2.0, 0.0))
        team.pose(7, t, (4.5, 2.0, math.pi))
        team.advance(t)
        while metrics.busy:
            metrics._job.result()
    # A scan that overtakes the pose of its own stamp waits for it.
    assert team.scan(3, 2.05, lambda pose: np.array([[pose[0] + 1.0, pose[1]]]))
    team.pose(3, 2.05, (3.05, 2.0, 0.0))
    cell3 = GridMap(np.full((40, 30), 100), 0.1)  # the left half
    team.cell(3, 2.0, cell3)
    team.cell(7, 2.0, GridMap(np.full((40, 29), 100), 0.1, (3.1, 0.0, 0.0)))
    with pytest.raises(ValueError, match="not finite"):
        team.pose(3, 2.1, (math.nan, 0.0, 0.0))
    team.remove_robot(7)
    metrics.close()
    rec.close()
    assert not warnings
    rows = read_rrd(tmp_path / "team.rrd")
    last_robots = rows["/world/robots"][-1][1]
    assert last_robots["Points3D:labels"] == ["robot_3"]  # 7 left
    first_two = [r for _, r in rows["/world/robots"] if len(r["Points3D:labels"]) == 2]
    assert first_two, "both robots were shown together"
    scans = rows["/world/scans/robot_3"]
    assert len(scans) == 1 and scans[0][0] == pytest.approx(2.05)
    assert scans[0][1]["Points3D:positions"][0][:2] == pytest.approx([4.05, 2.0])
    tail = rows["/world/trajectories/robot_3"][-1][1]["LineStrips3D:strips"][0]
    assert tail[0][:2] == pytest.approx([1.0, 2.0]) and tail[-1][:2] == pytest.approx([3.0, 2.0])
    # Computed cells first (the wall splits them at the door), then the published ones.
    cells = [(t, cell_rgba(r)) for t, r in rows["/world/cells"]]
    assert any(t < 2.0 for t, _ in cells)  # computed ones before the first published cell
    published = cells[-1][1]  # logged at the latest sim time, 2.05 s
    assert tuple(published[5, 5, :3]) == tuple(robot_color(3))
    assert tuple(published[5, 40, :3]) == tuple(robot_color(7))
    assert published[5, 30, 3] == 0  # the wall column is in nobody's published cell
    H = [r["Scalars:scalars"][0] for t, r in rows["/metrics/H"] if t is not None]
    assert len(H) >= 3 and all(h > 0 for h in H)
    m3 = {t: r["Scalars:scalars"][0] for t, r in rows["/metrics/mass/robot_3"] if t is not None}
    m7 = {t: r["Scalars:scalars"][0] for t, r in rows["/metrics/mass/robot_7"] if t is not None}
    from coverage_ros.core.geodesic.domain import CoverageDomain

    total = CoverageDomain.from_grid(grid, 0.1).mass_element.sum()
    # The cells of the robots posed at t cover the free space (robot 7 may miss the first
    # request, made when only robot 3's pose had arrived).
    assert len(set(m3) & set(m7)) >= 2
    for t in m3:
        assert m3[t] + m7.get(t, 0.0) == pytest.approx(total)
    assert rerun_verify(tmp_path / "team.rrd").returncode == 0


def test_config_is_validated():
    pytest.importorskip("rclpy")
    from coverage_ros.errors import ConfigError
    from coverage_ros.nodes.rerun_bridge import BridgeConfig

    assert BridgeConfig(record_path="x.rrd").rates().scan_decimation == 2
    for kwargs, message in [
        ({}, "no output"),
        ({"record_path": "/nonexistent/dir/x.rrd"}, "folder does not exist"),
        ({"connect_url": "http://localhost:9876"}, "rerun gRPC URL"),
        ({"serve_web": True, "web_port": 9876}, "must differ"),
        ({"record_path": "x.rrd", "metrics_period": -1.0}, "metrics_period"),
        ({"record_path": "x.rrd", "scan_decimation": 0}, "scan_decimation"),
        ({"record_path": "x.rrd", "robot_prefix": "robot/"}, "robot_prefix"),
    ]:
        with pytest.raises(ConfigError, match=message):
            BridgeConfig(**kwargs)


# ---------------------------------------------------------------------------- the real node
ROOM_0 = (0.5, 0.5, 3.5, 3.0)  # [m] xmin, ymin, xmax, ymax: robot 0's cell, bottom-left room
ROOM_1 = (8.5, 5.0, 11.5, 7.5)  # robot 1's cell, top-right room
CORRIDOR = (6.0, 4.0)  # in nobody's published cell
PLAN_0 = [(1.0, 1.0), (2.0, 1.5), (3.0, 2.5)]
GOAL = {0: (3.0, 2.5), 1: (10.0, 6.0)}


def cell_msg(room, stamp):
    """A cropped cell grid on the office map's lattice (origin -0.05, 0.05 m cells)."""
    from coverage_ros.nodes import conversions as conv

    res, x0, y0 = 0.05, -0.05, -0.05
    c0, r0 = round((room[0] - x0) / res), round((room[1] - y0) / res)
    c1, r1 = round((room[2] - x0) / res), round((room[3] - y0) / res)
    grid = GridMap(np.full((r1 - r0, c1 - c0), 100), res, (x0 + c0 * res, y0 + r0 * res, 0.0))
    return conv.grid_to_occupancy_grid(grid, stamp)


def robot_messages(robot_id: int, stamp) -> dict:
    from geometry_msgs.msg import Point32, PolygonStamped, PoseStamped
    from nav_msgs.msg import Path

    from coverage_ros.nodes import conversions as conv

    def pose(x, y):
        msg = PoseStamped()
        msg.header.stamp, msg.header.frame_id = stamp, "map"
        msg.pose.position.x, msg.pose.position.y = x, y
        msg.pose.orientation = conv.yaw_to_quaternion(0.0)
        return msg

    plan = Path()
    plan.header.stamp, plan.header.frame_id = stamp, "map"
    plan.poses = [pose(x + robot_id, y) for x, y in PLAN_0]
    state = conv.coverage_state_msg(stamp, {"x": 1.0, "y": 1.0, "weight": 0.0, "mass": 2.5,
                                            "update_ms": 12.0}, robot_id=robot_id)
    polygon = PolygonStamped()
    polygon.header.stamp, polygon.header.frame_id = stamp, "map"
    polygon.polygon.points = [Point32(x=x, y=y) for x, y in [(0.5, 0.5), (3.5, 0.5), (3.5, 3.0)]]
    room = ROOM_0 if robot_id == 0 else ROOM_1
    return {"cell": cell_msg(room, stamp), "plan": plan, "goal_pose": pose(*GOAL[robot_id]),
            "coverage_state": state, "cell_polygon": polygon}


@dataclass
class Run:
    rrd: object
    exit_code: int
    output: str
    truth: dict = field(default_factory=dict)  # robot id -> last ground-truth (x, y) at rest
    moved: float = 0.0  # [m] how far robot 0 drove


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """world_node (office, 2 robots) + the bridge; the test client acts as the robot nodes,
    drives robot 0, removes robot 1 and spawns robot 5, then stops the bridge with SIGINT."""
    pytest.importorskip("rclpy")
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Int32, String

    from coverage_ros.nodes import conversions as conv

    rrd = tmp_path_factory.mktemp("bridge") / "team.rrd"
    domain = domain_id(20)
    bridge_cmd = [sys.executable, "-m", "coverage_ros.nodes.rerun_bridge", "--ros-args"] + [
        a for p in (f"record_path:={rrd}", "recording_id:=bridge-test", "world:=office",
                    "metrics_period:=0.5", "cells_period:=0.2", "trajectory_period:=0.2",
                    "scan_period:=0.2", "scan_decimation:=1")
        for a in ("-p", p)]
    with NodeProcess.world_node(domain, "world:=office", "num_robots:=2", "seed:=2",
                                "real_time_factor:=2.0", "status_rate_hz:=2.0") as world, \
            NodeProcess(bridge_cmd, domain) as bridge:
        client = RosClient(domain)
        try:
            truth = {0: [], 1: [], 5: []}
            for rid in truth:
                client.node.create_subscription(
                    Odometry, f"/robot_{rid}/ground_truth",
                    lambda m, r=rid: truth[r].append(conv.odometry_to_pose(m)[:2]), 10)
            pubs = {rid: {kind: client.publisher(f"/robot_{rid}/{kind}", type(msg))
                          for kind, msg in robot_messages(rid, conv.to_time_msg(0.0)).items()}
                    for rid in (0, 1)}
            client.spin_until(lambda: truth[0] and truth[1], 60.0, "both robots' ground truth")

            def subscribed() -> bool:
                assert bridge.alive(), bridge.output()
                return all(p.get_subscription_count() > 0
                           for by_kind in pubs.values() for p in by_kind.values())

            client.spin_until(subscribed, 60.0, "the bridge to subscribe the robots' topics")

            # Robot 1 leaves only once the bridge has it on the map, and 2 s of sim time later
            # (scans every 0.2 s): a loaded machine had removed it before the world's ground
            # truth reached the bridge.
            client.spin_until(lambda: all(f"robot {rid}: first {what}" in bridge.output()
                                          for rid in (0, 1) for what in ("pose", "scan")),
                              60.0, "the bridge to have both robots' first pose and scan")
            since = conv.from_time_msg(client.wait_for("/clock", Clock).clock)
            now = client.wait_for("/clock", Clock,
                                  lambda m: conv.from_time_msg(m.clock) > since + 2.0, 30.0).clock
            for rid, by_kind in pubs.items():
                for kind, msg in robot_messages(rid, now).items():
                    by_kind[kind].publish(msg)
            # Bad input is dropped with a warning: a goal in another frame, a torn cell grid.
            bad_goal = robot_messages(0, now)["goal_pose"]
            bad_goal.header.frame_id = "robot_0/odom"
            pubs[0]["goal_pose"].publish(bad_goal)
            bad_cell = robot_messages(0, now)["cell"]
            bad_cell.info.width += 1
            pubs[0]["cell"].publish(bad_cell)
            pubs[0]["cell"].publish(robot_messages(0, now)["cell"])  # and a good one again
            start = np.array(truth[0][-1])
            cmd = client.publisher("/robot_0/cmd_vel", Twist)
            for _ in range(40):  # drive an arc for up to 4 s, until 0.15 m from the start
                if np.hypot(*(np.array(truth[0][-1]) - start)) > 0.15:
                    break
                cmd.publish(conv.command_to_twist(0.2, 0.3))
                client.spin_for(0.1)
            moved = float(np.hypot(*(np.array(truth[0][-1]) - start)))
            for p in pubs[1].values():  # robot 1's node goes away, then the robot itself
                client.node.destroy_publisher(p)
            client.publisher("/world/remove", Int32).publish(Int32(data=1))
            client.publisher("/world/spawn", String).publish(String(data="{id: 5}"))
            client.spin_until(lambda: truth[5], 30.0, "robot 5's ground truth")
            client.spin_until(lambda: "robot 1 left" in bridge.output()
                              and "robot 5: first pose" in bridge.output(), 60.0,
                              "the bridge to notice robot 1 leaving and robot 5 joining")
            since = conv.from_time_msg(client.wait_for("/clock", Clock).clock)
            client.wait_for("/clock", Clock,  # robot 0 brakes (cmd_vel timeout) and rests, and
                            lambda m: conv.from_time_msg(m.clock) > since + 3.0, 30.0)  # metrics
            last = {rid: tuple(truth[rid][-1]) for rid in (0, 5)}
        finally:
            client.close()
        bridge.signal(signal.SIGINT)
        code = bridge.proc.wait(timeout=30)
        assert world.alive(), world.output()
        yield Run(rrd, code, bridge.output(), last, moved)



@pytest.mark.integration
def test_bridge_exits_cleanly_with_a_complete_recording(run):
    assert run.exit_code == 0, run.output
    assert "Traceback" not in run.output, run.output
    dropped = [line for line in run.output.splitlines() if "dropped a message" in line]
    assert len(dropped) == 2, run.output
    text = "\n".join(dropped)
    assert "/robot_0/goal_pose: frame_id 'robot_0/odom', expected 'map'" in text
    assert "/robot_0/cell: OccupancyGrid.data: size does not match" in text
    verify = rerun_verify(run.rrd)
    assert verify.returncode == 0, verify.stdout + verify.stderr
    from rerun.chunk import RrdReader

    assert [e.recording_id for e in RrdReader(run.rrd).recordings()] == ["bridge-test"]


@pytest.mark.integration
def test_recording_has_every_layer(run):
    from rerun.chunk import RrdReader

    paths = set(RrdReader(run.rrd).store().schema().entity_paths())
    expected = {"/world/map", "/world/cells", "/world/robots", "/world/goals", "/metrics/H",
                "/world/cell_polygons/robot_0", "/state/robot_0", "/status/robot_0",
                "/status/world"}
    for rid in (0, 1):
        expected |= {f"/world/{kind}/robot_{rid}" for kind in ("trajectories", "plans", "scans")}
        expected.add(f"/metrics/mass/robot_{rid}")
    expected |= {"/world/trajectories/robot_5", "/metrics/mass/robot_5"}
    assert expected <= paths, sorted(expected - paths)


@pytest.mark.integration
def test_robots_follow_ground_truth_and_leave(run):
    rows = read_rrd(run.rrd)["/world/robots"]
    assert run.moved > 0.05, "robot 0 did not drive"
    _, last = rows[-1]
    assert last["Points3D:labels"] == ["robot_0", "robot_5"]  # robot 1 was removed
    for k, rid in enumerate((0, 5)):
        assert last["Points3D:positions"][k][:2] == pytest.approx(run.truth[rid], abs=1e-3)
    assert any(r["Points3D:labels"] == ["robot_0", "robot_1"] for _, r in rows)
    tail = read_rrd(run.rrd)["/world/trajectories/robot_0"][-1][1]["LineStrips3D:strips"][0]
    assert len(tail) >= 2 and tail[-1][:2] == pytest.approx(run.truth[0], abs=0.03)


@pytest.mark.integration
def test_published_cells_plans_and_goals_are_drawn(run):
    from coverage_ros.core.world import load_world
    from coverage_ros.worlds import resolve_world_path

    grid = load_world(resolve_world_path("office")).grid
    rows = read_rrd(run.rrd)

    def pixel(rgba, x, y):
        r, c = grid.world_to_cell(np.array([[x, y]]))[0]
        return tuple(rgba[r, c])

    def centre(room):
        return 0.5 * (room[0] + room[2]), 0.5 * (room[1] + room[3])

    both = [rgba for _, r in rows["/world/cells"] for rgba in [cell_rgba(r)]
            if pixel(rgba, *centre(ROOM_0))[:3] == tuple(robot_color(0))
            and pixel(rgba, *centre(ROOM_1))[:3] == tuple(robot_color(1))
            and pixel(rgba, *CORRIDOR)[3] == 0]
    assert both, "no cell layer with robot 0's and robot 1's published cells"
    rgba = both[-1]
    assert pixel(rgba, 3.4, 2.9)[3] == 255 and pixel(rgba, 3.6, 2.9)[3] == 0  # cell border
    plan = rows["/world/plans/robot_0"][-1][1]["LineStrips3D:strips"][0]
    np.testing.assert_allclose(np.array(plan)[:, :2], PLAN_0, atol=1e-6)
    goals = [np.array(r["Points3D:positions"])[:, :2] for _, r in rows["/world/goals"]]
    assert any(len(g) == 2 and np.allclose(g, [GOAL[0], GOAL[1]], atol=1e-6) for g in goals)
    names = [r for t, r in rows["/state/robot_0"] if t is None][-1]["SeriesLines:names"]
    values = [r for t, r in rows["/state/robot_0"] if t is not None][-1]["Scalars:scalars"]
    assert dict(zip(names, values, strict=True)) == {
        "x": 1.0, "y": 1.0, "weight": 0.0, "mass": 2.5, "update_ms": 12.0}
    names = [r for t, r in rows["/status/robot_0"] if t is None][-1]["SeriesLines:names"]
    assert {"collisions", "path_length"} <= set(names) and "x" not in names


@pytest.mark.integration
def test_scans_lie_on_walls_or_other_robots(run):
    """Every lidar hit, placed with the robot's pose at the scan's stamp, is on the surface of
    a map obstacle or of another robot - robot 0 scans while it turns and drives."""
    from scipy import ndimage

    from coverage_ros.core.world import load_world
    from coverage_ros.worlds import resolve_world_path

    world = load_world(resolve_world_path("office"))
    grid = world.grid
    # [m] distance from each cell centre to the nearest occupied cell
    to_wall = ndimage.distance_transform_edt(~grid.occupied_mask()) * grid.resolution
    rows = read_rrd(run.rrd)
    track: dict[str, list] = {}  # robot label -> [(t, (x, y)), ...] from the robot markers
    for t, row in rows["/world/robots"]:
        for p, name in zip(row["Points3D:positions"], row["Points3D:labels"], strict=True):
            track.setdefault(name, []).append((t, p[:2]))
    for rid in (0, 1):
        scans = [(t, r) for t, r in rows[f"/world/scans/robot_{rid}"]
                 if "Points3D:positions" in r]  # the others clear the scan (robot 1 left)
        assert len(scans) >= 3
        for t, row in scans:
            pts = np.array(row["Points3D:positions"])[:, :2]
            assert len(pts) > 50
            cells = np.clip(grid.world_to_cell(pts), 0, [grid.height - 1, grid.width - 1])
            on_wall = to_wall[cells[:, 0], cells[:, 1]] <= 1.5 * grid.resolution
            others = np.array([min(samples, key=lambda s: abs(s[0] - t))[1]
                               for name, samples in track.items()
                               if name != f"robot_{rid}"]).reshape(-1, 2)
            gap = np.hypot(*(pts[:, None, :] - others[None]).transpose(2, 0, 1))
            on_robot = (gap < world.robot.radius + 0.05).any(axis=1)
            assert np.mean(on_wall | on_robot) > 0.99, (rid, t, pts[~(on_wall | on_robot)])


@pytest.mark.integration
def test_metrics_cover_the_free_space(run):
    from coverage_ros.core.geodesic.domain import CoverageDomain
    from coverage_ros.core.world import load_world
    from coverage_ros.worlds import resolve_world_path

    world = load_world(resolve_world_path("office"))
    total = CoverageDomain.from_grid(world.grid, world.robot.radius).mass_element.sum()
    rows = read_rrd(run.rrd)
    H = [(t, r["Scalars:scalars"][0]) for t, r in rows["/metrics/H"] if t is not None]
    assert len(H) >= 3 and all(h > 0 and math.isfinite(h) for _, h in H)
    masses: dict[float, float] = {}
    for rid in (0, 1, 5):
        for t, r in rows.get(f"/metrics/mass/robot_{rid}", []):
            if t is not None:
                masses[t] = masses.get(t, 0.0) + r["Scalars:scalars"][0]
    # The office is one connected free space: the cells of all robots cover all of it.
    assert all(m == pytest.approx(total, rel=1e-6) for m in masses.values())


def free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def listening_addresses(port: int) -> set[str]:
    """Local addresses with a listening TCP socket on ``port`` (from /proc/net/tcp and tcp6):
    IPv4 dotted, IPv6 as ``ipv6:<hex>``."""
    from pathlib import Path

    found = set()
    for table in ("tcp", "tcp6"):
        path = Path("/proc/net") / table
        for line in (path.read_text().splitlines()[1:] if path.exists() else []):
            local, _, state = line.split()[1:4]
            addr, hex_port = local.split(":")
            if state != "0A" or int(hex_port, 16) != port:  # 0A: LISTEN
                continue
            found.add(".".join(str(int(addr[i:i + 2], 16)) for i in (6, 4, 2, 0))
                      if table == "tcp" else f"ipv6:{addr}")
    return found


@pytest.mark.integration
def test_web_viewer_listens_on_localhost_only_and_stops_with_the_bridge(tmp_path):
    pytest.importorskip("rclpy")
    import time
    import urllib.request

    web, grpc = free_port(), free_port()
    rrd = tmp_path / "web.rrd"
    cmd = [sys.executable, "-m", "coverage_ros.nodes.rerun_bridge", "--ros-args", "-p",
           "serve_web:=true", "-p", f"web_port:={web}", "-p", f"grpc_port:={grpc}", "-p",
           f"record_path:={rrd}"]
    with NodeProcess(cmd, domain_id(21)) as bridge:
        deadline = time.monotonic() + 60.0
        while "web viewer http://127.0.0.1" not in bridge.output():
            assert bridge.alive() and time.monotonic() < deadline, bridge.output()
            time.sleep(0.1)
        assert listening_addresses(web) == {"127.0.0.1"}
        assert listening_addresses(grpc) == {"127.0.0.1"}
        with urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=10) as page:
            assert page.status == 200
        bridge.signal(signal.SIGINT)
        assert bridge.proc.wait(timeout=20) == 0, bridge.output()
    assert not listening_addresses(web) and not listening_addresses(grpc)  # server stopped
    assert rerun_verify(rrd).returncode == 0


def test_ros2_run_layout_has_the_console_script():
    exe = REPO / "install" / "coverage_ros" / "lib" / "coverage_ros" / "rerun_bridge"
    assert exe.exists(), "colcon's ros2 run layout has the console script"
    out = subprocess.run([str(REPO / ".venv" / "bin" / "rerun_bridge")], capture_output=True,
                         text=True, timeout=60,
                         env={**os.environ, "ROS_DOMAIN_ID": str(domain_id(22)),
                              "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    assert out.returncode == 2
    assert out.stderr.strip() == ("rerun_bridge: error: record_path: no output: set "
                                  "record_path, connect_url or serve_web (got '')")


def test_a_saved_recording_opens_at_its_end_and_shows_the_region(tmp_path):
    """The blueprint's time panel follows the newest data: a saved file opens on the team at
    its end, not on an empty map at its first second. The region of interest is a layer."""
    from rerun.chunk import RrdReader

    from coverage_ros.viz.recording import CoverageRecorder

    path = tmp_path / "r.rrd"
    rec = CoverageRecorder()
    rec.set_outputs(path)
    rec.log_map(GridMap(np.zeros((10, 10), np.int8), 0.1))
    rec.send_blueprint()
    rec.set_time(1.0)
    rec.log_robots([0], np.array([[0.5, 0.5]]), [0.1])
    rec.log_region([np.array([[0.1, 0.1], [0.6, 0.1], [0.6, 0.6]])])
    rec.close()
    reader = RrdReader(path)
    states = []
    for bp in reader.blueprints():
        for chunk in reader.store(store=bp).stream():
            batch = chunk.to_record_batch()
            if "TimePanelBlueprint:play_state" in batch.schema.names:
                states += batch.column("TimePanelBlueprint:play_state").to_pylist()
    assert states and all(s == [3] for s in states), states  # 3: following
    region = read_rrd(path)["/world/region"]
    strips = region[-1][1]["LineStrips3D:strips"][0]
    assert len(strips) == 4  # closed triangle


def test_a_recording_that_cannot_be_indexed_is_left_as_it_was(tmp_path):
    from coverage_ros.viz.recording import index_recording

    bad = tmp_path / "broken.rrd"
    bad.write_bytes(b"not a recording at all")
    problem = index_recording(bad)
    assert problem is not None and "without rerun's chunk index" in problem
    assert bad.read_bytes() == b"not a recording at all"
    assert [p.name for p in tmp_path.iterdir()] == ["broken.rrd"]  # no half-written file left
