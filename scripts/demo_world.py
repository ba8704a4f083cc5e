"""Demo until the team launcher exists: a world node plus a scripted driver for 4 robots.

Starts ``world_node`` (office world, 4 robots) in its own process group on a private DDS domain,
drives the robots with simple patterns for 20 s of sim time from a plain rclpy client, then
prints what happened: distance driven, collisions, scans received, sim time vs wall time.
Run through ``scripts/demo``, which sets up the environment first.
"""

from __future__ import annotations

import argparse
import math
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import qos_profile_sensor_data
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan

from coverage_ros.nodes import conversions as conv

NUM_ROBOTS = 4
COMMAND_PERIOD = 0.1  # [s] sim time between commands (a 10 Hz controller)
PATTERNS = ("circle", "square", "slalom", "bumper car")


def command(pattern: str, t: float, front: float, state: dict) -> tuple[float, float]:
    """``(v, w)`` for a pattern at sim time ``t`` [s]; ``front`` [m] is the nearest lidar
    return ahead."""
    if pattern == "circle":
        return 0.15, 0.6
    if pattern == "square":  # 3 s straight, then a quarter turn (pi/2 at 1 rad/s)
        phase = t % (3.0 + math.pi / 2)
        return (0.15, 0.0) if phase < 3.0 else (0.0, 1.0)
    if pattern == "slalom":
        return 0.18, 1.0 * math.sin(1.2 * t)
    # Bumper car: straight on until something is close ahead, then back off and turn.
    if state.get("until", -1.0) > t:
        return -0.05, 1.5
    if front < 0.2:
        state["until"] = t + 1.5
    return 0.22, 0.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="office")
    parser.add_argument("--seconds", type=float, default=20.0, help="sim seconds (20)")
    parser.add_argument("--rtf", type=float, default=2.0, help="real_time_factor (2)")
    args = parser.parse_args()
    domain = int(os.environ.get("ROS_DOMAIN_ID") or random.randint(100, 199))
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    log = Path(tempfile.mkstemp(prefix="demo-world-", suffix=".log")[1])
    cmd = [sys.executable, "-m", "coverage_ros.nodes.world_node", "--ros-args",
           "-p", f"world:={args.world}", "-p", f"num_robots:={NUM_ROBOTS}",
           "-p", f"real_time_factor:={args.rtf}", "-p", "seed:=1"]
    print(f"[demo] world_node on '{args.world}', {NUM_ROBOTS} robots, rtf {args.rtf:g}, "
          f"ROS_DOMAIN_ID={domain} (log: {log})")
    with log.open("w") as out:
        node_proc = subprocess.Popen(cmd, env=env, stdout=out, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, start_new_session=True)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node("demo_driver", context=context)
    rc = 1
    try:
        rc = drive(node, context, node_proc, log, args)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        if node_proc.poll() is None:
            os.killpg(node_proc.pid, signal.SIGINT)
            try:
                node_proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(node_proc.pid, signal.SIGKILL)
                node_proc.wait()
    if rc == 0 and node_proc.returncode == 0:
        log.unlink()  # keep the log only when something went wrong
    return rc


def drive(node, context, node_proc, log: Path, args) -> int:
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    sim = {"t": -1.0}
    scans = [0] * NUM_ROBOTS
    front = [math.inf] * NUM_ROBOTS
    odom: list = [None] * NUM_ROBOTS
    status: dict = {}
    node.create_subscription(Clock, "/clock", lambda m: sim.update(t=conv.from_time_msg(m.clock)),
                             10)
    node.create_subscription(DiagnosticArray, "/world/robots", lambda m: status.update(
        {s.name: conv.diagnostic_values(s) for s in m.status}), 10)
    pubs = []
    for i in range(NUM_ROBOTS):
        frames = conv.RobotFrames.of("robot_", i)
        pubs.append(node.create_publisher(Twist, frames.topic("cmd_vel"), 10))

        def on_scan(msg, i=i):
            scans[i] += 1
            angles, ranges = conv.laser_scan_to_ranges(msg)
            ahead = ranges[(abs(angles) < 0.4)]
            front[i] = float(min(abs(ahead))) if len(ahead) else math.inf

        node.create_subscription(LaserScan, frames.topic("scan"), on_scan,
                                 qos_profile_sensor_data)
        node.create_subscription(Odometry, frames.topic("odom"),
                                 lambda m, i=i: odom.__setitem__(i, m), 10)
    deadline = time.monotonic() + 30.0
    while sim["t"] < 0:
        executor.spin_once(timeout_sec=0.1)
        if node_proc.poll() is not None or time.monotonic() > deadline:
            print("[demo] world_node did not start:\n" + log.read_text(), file=sys.stderr)
            return 1
    wall0, sim0 = time.monotonic(), sim["t"]
    state: list[dict] = [{} for _ in range(NUM_ROBOTS)]
    next_cmd = sim0
    last_report = sim0
    while sim["t"] < sim0 + args.seconds:
        executor.spin_once(timeout_sec=0.01)
        if node_proc.poll() is not None:
            print("[demo] world_node exited:\n" + log.read_text(), file=sys.stderr)
            return 1
        t = sim["t"]
        if t >= next_cmd:
            next_cmd = t + COMMAND_PERIOD
            for i, pattern in enumerate(PATTERNS):
                v, w = command(pattern, t - sim0, front[i], state[i])
                pubs[i].publish(conv.command_to_twist(v, w))
        if t - last_report >= 5.0:
            last_report = t
            print(f"[demo] sim {t - sim0:5.1f} s, wall {time.monotonic() - wall0:5.1f} s")
    for pub in pubs:
        pub.publish(conv.command_to_twist(0.0, 0.0))
    wall = time.monotonic() - wall0
    simulated = sim["t"] - sim0
    status.clear()  # wait for a fresh status so the numbers include the whole run
    end = time.monotonic() + 3.0
    while not status and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.1)
    print(f"[demo] {simulated:.1f} s sim in {wall:.1f} s wall (rtf {simulated / wall:.2f})")
    print(f"[demo] {'robot':<9}{'pattern':<12}{'driven [m]':>11}{'collisions':>11}"
          f"{'scans':>7}   odom pose (x, y, yaw)")
    for i, pattern in enumerate(PATTERNS):
        s = status.get(f"robot_{i}", {})
        pose = conv.odometry_to_pose(odom[i]) if odom[i] is not None else (math.nan,) * 3
        print(f"[demo] robot_{i:<3}{pattern:<12}{float(s.get('path_length', 'nan')):>11.2f}"
              f"{s.get('collisions', '?'):>11}{scans[i]:>7}   "
              f"({pose[0]:.2f}, {pose[1]:.2f}, {pose[2]:.2f})")
    ok = all(scans) and all(o is not None for o in odom) and bool(status)
    print("[demo] done" if ok else "[demo] some topics were missing (see the log above)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
