"""The rerun bridge as a real node: it streams a world node's team (plus messages a test client
publishes as the robots) into a .rrd file; its web viewer (the layers without ROS:
unit/viz/test_live_team.py, test_viz_team.py, test_recording.py)."""

from __future__ import annotations

import math
import signal
import sys
from dataclasses import dataclass, field

import numpy as np
import pytest
from rosutil import NodeProcess, RosClient, domain_id
from rrdutil import cell_rgba, read_rrd, rerun_verify

from coverage_ros.core.world.grid import GridMap
from coverage_ros.viz.colors import robot_color

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
            # The world's inputs, matched before use (a volatile sample sent before its
            # subscriber is found is lost).
            cmd = client.publisher("/robot_0/cmd_vel", Twist)
            remove = client.publisher("/world/remove", Int32)
            spawn = client.publisher("/world/spawn", String)
            client.spin_until(lambda: truth[0] and truth[1], 60.0, "both robots' ground truth")

            def subscribed() -> bool:
                assert bridge.alive(), bridge.output()
                return all(p.get_subscription_count() > 0
                           for by_kind in pubs.values() for p in by_kind.values()) and all(
                    p.get_subscription_count() > 0 for p in (cmd, remove, spawn))

            client.spin_until(subscribed, 60.0, "the bridge and the world to subscribe")

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
            for _ in range(40):  # drive an arc for up to 4 s, until 0.15 m from the start
                if np.hypot(*(np.array(truth[0][-1]) - start)) > 0.15:
                    break
                cmd.publish(conv.command_to_twist(0.2, 0.3))
                client.spin_for(0.1)
            moved = float(np.hypot(*(np.array(truth[0][-1]) - start)))
            for p in pubs[1].values():  # robot 1's node goes away, then the robot itself
                client.node.destroy_publisher(p)
            remove.publish(Int32(data=1))
            spawn.publish(String(data="{id: 5}"))
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


