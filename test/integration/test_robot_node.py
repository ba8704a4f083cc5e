"""robot_node as a real process, checked over DDS from a plain rclpy client."""

from __future__ import annotations

import contextlib
import math
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import REPO, entry_point
from rosutil import NodeProcess, RosClient, domain_id, ros_env

INSTALL = REPO / "install" / "coverage_ros"
START = (1.0, 1.0, 0.0)  # office, bottom-left room


def robot_exe(env: dict) -> str:
    """The ros2-run executable, found the way `ros2 run` finds it: through the ament index."""
    code = ("from ament_index_python.packages import get_package_prefix as p; "
            "print(p('coverage_ros'))")
    prefix = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                            text=True, check=True).stdout.strip()
    exe = f"{prefix}/lib/coverage_ros/robot_node"
    assert prefix == str(INSTALL), prefix
    return exe


@pytest.fixture(scope="module")
def team():
    """World (office, one robot at START) + robot 0 started as `ros2 run` would."""
    domain = domain_id(10)
    env = ros_env(domain, AMENT_PREFIX_PATH=str(INSTALL))
    exe = robot_exe(env)
    world = NodeProcess.world_node(domain, "world:=office", "starts:=1.0,1.0,0.0")
    robot = NodeProcess([exe, "--ros-args", "-r", "__ns:=/robot_0", "-p", "robot_id:=0",
                         "-p", "use_sim_time:=true", "-p", "world:=office",
                         "-p", "neighbour_timeout:=1.5",
                         # A team of two whose other robot never comes: it listens for it
                         # (listen_timeout) and then starts alone, saying so.
                         "-p", "team_size:=2", "-p", "listen_timeout:=3.0"], domain, env)
    client = RosClient(domain)
    yield world, robot, client
    client.close()
    robot.stop()
    world.stop()


def test_robot_publishes_its_state_goal_plan_cell_and_commands(team):
    from coverage_msgs.msg import RobotState
    from geometry_msgs.msg import PoseStamped, Twist
    from nav_msgs.msg import OccupancyGrid, Odometry, Path

    from coverage_ros.nodes import conversions as conv

    world, robot, client = team
    # Every state names position and radius (before the first update there is no mass yet).
    first = client.wait_for("/robot_0/coverage_state", RobotState, timeout=40.0)
    assert {"x", "y", "radius"} <= set(conv.coverage_state_values(first))
    state = client.wait_for("/robot_0/coverage_state", RobotState,
                            lambda m: "mass" in conv.coverage_state_values(m), timeout=20.0)
    values = conv.coverage_state_values(state)
    truth = client.wait_for("/robot_0/ground_truth", Odometry, timeout=10.0)
    x, y, _ = conv.odometry_to_pose(truth)
    assert math.hypot(values["x"] - x, values["y"] - y) < 0.3
    assert values["mass"] > 0 and values["radius"] == pytest.approx(0.105)
    goal = client.wait_for("/robot_0/goal_pose", PoseStamped, timeout=10.0)
    assert goal.header.frame_id == "map"
    plan = client.wait_for("/robot_0/plan", Path, timeout=10.0)
    assert len(plan.poses) >= 2
    cell = client.wait_for("/robot_0/cell", OccupancyGrid, timeout=10.0)
    data = np.frombuffer(bytes(cell.data), dtype=np.int8)
    # Alone in the office, its cell is everything it can reach: most of the 12 x 8 m floor.
    assert (data == 100).sum() * cell.info.resolution ** 2 > 40.0
    moving = client.wait_for("/robot_0/cmd_vel", Twist, lambda m: abs(m.linear.x) > 0.01,
                             timeout=10.0)
    assert abs(moving.linear.x) <= 0.22 + 1e-9 and abs(moving.angular.z) <= 2.84 + 1e-9
    assert robot.alive() and world.alive()
    assert "heard 0 of the 1 other robots (team_size 2)" in robot.output()


def test_neighbours_are_discovered_and_bad_states_dropped(team):
    from coverage_msgs.msg import RobotState
    from nav_msgs.msg import OccupancyGrid

    from coverage_ros.nodes import conversions as conv

    _, robot, client = team
    pub = client.publisher("/robot_7/coverage_state", RobotState)
    bad_pubs = {k: client.publisher(f"/robot_{k}/coverage_state", RobotState)
                for k in (8, 9, 10)}
    neighbour = (1.0, 2.5)  # same room, above the robot: it takes the upper half

    def publish_all():
        stamp = conv.to_time_msg(0.0)
        pub.publish(conv.coverage_state_msg(stamp, {"x": neighbour[0], "y": neighbour[1]}))
        bad_pubs[8].publish(conv.coverage_state_msg(stamp, {"x": math.nan, "y": 1.0}))
        bad_pubs[9].publish(conv.coverage_state_msg(stamp, {"x": 1.0, "y": 1.0}, "odom"))
        bad_pubs[10].publish(conv.coverage_state_msg(stamp, {"x": 80.0, "y": 1.0}))

    def cell_excludes_neighbour(msg) -> bool:
        if msg.info.width == 0:
            return False
        data = np.frombuffer(bytes(msg.data), dtype=np.int8).reshape(msg.info.height,
                                                                      msg.info.width)
        col = int((neighbour[0] - msg.info.origin.position.x) / msg.info.resolution)
        row = int((neighbour[1] - msg.info.origin.position.y) / msg.info.resolution)
        inside = 0 <= row < msg.info.height and 0 <= col < msg.info.width
        return not inside or data[row, col] != 100

    cells = client.subscribe("/robot_0/cell", OccupancyGrid)
    deadline_spins = 0
    while not (cells and cell_excludes_neighbour(cells[-1])):
        publish_all()
        client.spin_for(0.2)
        deadline_spins += 1
        assert deadline_spins < 150, "the robot never took its neighbour into account"
    assert robot.alive()
    # Each bad sender is dropped once the robot has found its topic (discovery runs every
    # DISCOVERY_PERIOD, independently of when the cell first left the neighbour out).
    expected = ("neighbour 7 found", "dropped coverage_state of robot 8",
                "dropped coverage_state of robot 9", "dropped coverage_state of robot 10")

    # 60 s: a robot that has heard its team looks at the graph every ~10 s, and one look may
    # miss a publisher that was just made
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        if all(text in robot.output() for text in expected):
            break
        publish_all()
        client.spin_for(0.2)
    missing = [text for text in expected if text not in robot.output()]
    assert not missing, f"not in the robot's log after 60 s: {missing}"
    log = robot.output()
    assert "dropped coverage_state of robot 8" in log and "nan" in log
    assert "dropped coverage_state of robot 9" in log and "frame_id 'odom'" in log
    assert "dropped coverage_state of robot 10" in log and "outside the map" in log
    # Once the neighbour falls silent it is dropped again after neighbour_timeout.
    cells.clear()
    client.spin_until(lambda: cells and not cell_excludes_neighbour(cells[-1]), timeout=20.0,
                      what="the cell to grow back after the neighbour went silent")


def test_update_worker_keeps_within_its_cpu_budget():
    """By every start, the calls before it used at most burst + load x elapsed CPU seconds;
    busy requests are refused; a costly call is absorbed by the credit; an exception in a call
    does not stop the worker."""
    import threading
    import time

    from coverage_ros.nodes.robot_node import UpdateWorker

    started = threading.Event()
    release = threading.Event()

    def run(now):
        if now < 0:
            raise ValueError("bad update")
        if now == 1:
            started.set()
            release.wait(5.0)
        sum(range(100_000 if now < 3 else 2_000_000))

    load, burst = 0.25, 0.005
    errors = []
    worker = UpdateWorker(run, load, on_error=errors.append, burst=burst)
    try:
        assert worker.request(1.0)
        assert started.wait(5.0)
        assert not worker.request(2.0)  # busy
        release.set()
        t0 = time.monotonic()
        requests = 0
        while len(worker.cpu_ms) < 8 and time.monotonic() - t0 < 20.0:
            requests += worker.request(-1.0 if len(worker.cpu_ms) == 3 else 2.0)
            time.sleep(0.0005)
        assert len(worker.cpu_ms) >= 8
        assert requests < 5000  # most requests were refused while waiting
        used = np.cumsum(worker.cpu_ms) / 1e3
        allowed = burst + load * (np.array(list(worker.starts)[1:]) - worker.created)
        assert np.all(used[:-1] <= allowed + 1e-6)
        assert len(errors) == 1 and isinstance(errors[0], ValueError)
        assert "coverage updates" in worker.summary()
    finally:
        release.set()
        worker.close()

    # A large credit absorbs one costly call: the next may start right after it.
    worker = UpdateWorker(run, 0.001, burst=5.0)
    try:
        assert worker.request(3.0)
        t0 = time.monotonic()
        while not worker.cpu_ms and time.monotonic() - t0 < 20.0:
            time.sleep(0.001)
        while worker._busy:
            time.sleep(0.001)
        assert worker.cpu_ms[0] > 10.0  # a costly call (10 ms at load 0.001: 10 s of waiting)
        assert worker.request(4.0)
    finally:
        worker.close()


@pytest.mark.parametrize("end", ["q", signal.SIGINT, signal.SIGTERM],
                         ids=["q", "SIGINT", "SIGTERM"])
def test_coverage_teleop_takes_the_robot_over_and_hands_it_back(team, end):
    """The terminal teleop in a real terminal (a pty): two presses of the left arrow turn the
    robot in place at 2/5 of its turn rate; 'q' - or Ctrl-C's SIGINT, or SIGTERM - stops it and
    gives it back to its strategy."""
    import os
    import pty
    import time

    from geometry_msgs.msg import Twist

    _world, robot, client = team
    cmds = client.subscribe("/robot_0/cmd_vel", Twist)
    start = len(robot.output())
    master, slave = pty.openpty()
    teleop = subprocess.Popen([entry_point("coverage-teleop"), "--robot", "0",
                               "--domain-id", str(domain_id(10))],
                              stdin=slave, stdout=slave, stderr=slave, start_new_session=True,
                              env=ros_env(domain_id(10)))
    os.close(slave)
    try:
        client.spin_until(lambda: "manual: driven by teleop/cmd_vel" in robot.output()[start:],
                          30, "the robot to be taken over")
        os.write(master, b"\x1b[D\x1b[D")
        cmds.clear()

        def turning() -> list[tuple[float, float]]:
            return [(m.linear.x, m.angular.z) for m in cmds[-5:]]

        def turns_left() -> bool:  # the last five commands: on the spot, two steps to the left
            return len(cmds) >= 5 and all(v == 0.0 and abs(w - 2 * 2.84 / 5) < 1e-6
                                          for v, w in turning())

        with contextlib.suppress(TimeoutError):
            client.spin_until(turns_left, 15, "two left steps")
        assert turns_left(), turning()
        mark = len(robot.output())
        if end == "q":
            os.write(master, b"q")
        else:
            os.killpg(teleop.pid, end)
        assert teleop.wait(timeout=20) == 0
    finally:
        if teleop.poll() is None:
            teleop.kill()
        os.close(master)
    deadline = time.monotonic() + 10
    while "robot 0: autonomous" not in robot.output()[mark:] and time.monotonic() < deadline:
        client.spin_for(0.2)
    assert "robot 0: autonomous" in robot.output()[mark:]


@pytest.mark.parametrize("kind", ["", "single"])
def test_a_robot_on_either_executor_covers_and_stops_cleanly(kind):
    """Without COVERAGE_ROS_EXECUTOR a robot runs on rclpy's EventsExecutor, with ``single``
    (coverage-team --executor single) on the SingleThreadedExecutor; on either it updates,
    drives and ends on SIGINT with code 0 and its exit log - its last command a zero velocity,
    sent before ROS shuts down (it leaves the robot standing), and its summary on /rosout."""
    from coverage_msgs.msg import RobotState
    from geometry_msgs.msg import Twist
    from rcl_interfaces.msg import Log

    from coverage_ros.nodes import conversions as conv

    domain = domain_id(12)
    env = ros_env(domain, COVERAGE_ROS_EXECUTOR=kind)
    with NodeProcess.world_node(domain, "world:=office", "starts:=1.0,1.0,0.0") as world, \
            NodeProcess([sys.executable, "-m", "coverage_ros.nodes.robot_node", "--ros-args",
                         "-r", "__ns:=/robot_0", "-p", "robot_id:=0", "-p", "use_sim_time:=true",
                         "-p", "world:=office"], domain, env) as robot:
        client = RosClient(domain)
        try:
            client.wait_for("/robot_0/coverage_state", RobotState,
                            lambda m: "mass" in conv.coverage_state_values(m), timeout=40.0)
            commands = client.subscribe("/robot_0/cmd_vel", Twist)
            logs = client.subscribe("/rosout", Log, 100)
            client.spin_until(lambda: any(abs(m.linear.x) > 0.01 for m in commands), 20.0,
                              "the robot driving")
            # Its state carries the velocity it drives at (neighbours' safety filters).
            client.wait_for("/robot_0/coverage_state", RobotState, lambda m: math.hypot(
                conv.coverage_state_values(m).get("vx", 0.0),
                conv.coverage_state_values(m).get("vy", 0.0)) > 0.01, timeout=10.0)
            assert world.alive() and robot.alive()
            robot.signal(signal.SIGINT)
            client.spin_until(lambda: not robot.alive(), 10.0, "the robot's exit")
            client.spin_for(0.5)
        finally:
            client.close()
        assert robot.stop(timeout=10.0) == 0, robot.output()
        assert f"executor: {kind or 'events'} " in robot.output()
        assert "coverage updates, one every" in robot.output()
        assert "Failed to publish" not in robot.output()
        last = commands[-1]
        assert (last.linear.x, last.angular.z) == (0.0, 0.0), last
        assert any("coverage updates, one every" in m.msg for m in logs)
