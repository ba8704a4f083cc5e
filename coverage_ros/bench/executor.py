"""CPU per message of rclpy's executors, as a robot process sees its traffic
(``scripts/bench_executor``).

A publisher process sends what a robot of a 16-robot team receives - 15 neighbours'
``coverage_state`` at 2.5 Hz, its ground truth at 10 Hz, ``/clock`` at 10 Hz, its scan at 5 Hz -
to a listener process whose node subscribes to all of it and runs a 10 Hz tracking timer and a
2 Hz "update" timer, either with the ``SingleThreadedExecutor`` (what robot_node uses, with its
own update thread), with a ``MultiThreadedExecutor`` and the update timer in a
``MutuallyExclusiveCallbackGroup`` (ros2/examples' callback_group.py), or with rclpy's
``EventsExecutor`` (``rclpy.experimental``: its dispatch loop in C++). The listener's CPU time
over the window, per message received, is the figure; the last stdout line is JSON.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

NEIGHBOURS = 15  # a robot of a 16-robot team hears 15 others
STATE_HZ = 2.5  # [Hz] coverage_state of each neighbour
POSE_HZ = 10.0  # [Hz] ground_truth and /clock
SCAN_HZ = 5.0  # [Hz] lidar


def _publisher(seconds: float) -> None:
    import rclpy
    from coverage_msgs.msg import RobotState
    from nav_msgs.msg import Odometry
    from rclpy.executors import ExternalShutdownException
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import LaserScan

    rclpy.init()
    node = rclpy.create_node("bench_publisher")
    states = [node.create_publisher(RobotState, f"/robot_{k}/coverage_state", 10)
              for k in range(1, NEIGHBOURS + 1)]
    pose = node.create_publisher(Odometry, "/robot_0/ground_truth", 10)
    clock = node.create_publisher(Clock, "/clock", 10)
    scan = node.create_publisher(LaserScan, "/robot_0/scan", 10)
    msg = RobotState(x=1.0, y=1.0, weight=1.0, mass=1.0, cost=1.0)
    laser = LaserScan(ranges=[1.0] * 360)

    def publish_states() -> None:
        for p in states:
            p.publish(msg)

    def publish_pose() -> None:
        pose.publish(Odometry())
        clock.publish(Clock())

    node.create_timer(1.0 / STATE_HZ, publish_states)
    node.create_timer(1.0 / POSE_HZ, publish_pose)
    node.create_timer(1.0 / SCAN_HZ, lambda: scan.publish(laser))
    end = time.monotonic() + seconds
    with contextlib.suppress(KeyboardInterrupt, ExternalShutdownException):
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
    rclpy.try_shutdown()


def _listener(kind: str, warmup: float, seconds: float) -> None:
    import rclpy
    from coverage_msgs.msg import RobotState
    from nav_msgs.msg import Odometry
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
    from rclpy.experimental.events_executor import EventsExecutor
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import LaserScan

    rclpy.init()
    node = rclpy.create_node("bench_listener")
    count = [0]

    def got(_msg) -> None:
        count[0] += 1

    for k in range(1, NEIGHBOURS + 1):
        node.create_subscription(RobotState, f"/robot_{k}/coverage_state", got, 10)
    node.create_subscription(Odometry, "/robot_0/ground_truth", got, 10)
    node.create_subscription(Clock, "/clock", got, 10)
    node.create_subscription(LaserScan, "/robot_0/scan", got, 10)
    node.create_timer(0.1, lambda: None)  # tracking
    group = MutuallyExclusiveCallbackGroup() if kind == "multi" else None
    node.create_timer(0.5, lambda: None, callback_group=group)  # coverage update
    executors: dict[str, Callable[[], Any]] = {
        "multi": MultiThreadedExecutor, "single": SingleThreadedExecutor,
        "events": EventsExecutor}
    executor = executors[kind]()
    executor.add_node(node)
    end_warm = time.monotonic() + warmup
    while time.monotonic() < end_warm:
        executor.spin_once(timeout_sec=0.05)
    n0, cpu0, t0 = count[0], time.process_time(), time.monotonic()
    while time.monotonic() - t0 < seconds:
        executor.spin_once(timeout_sec=0.05)
    cpu, n = time.process_time() - cpu0, count[0] - n0
    print(json.dumps({"executor": kind, "messages": n, "cpu_s": round(cpu, 3),
                      "cpu_percent": round(100 * cpu / seconds, 1),
                      "us_per_message": round(1e6 * cpu / max(n, 1), 1)}), flush=True)
    executor.shutdown()
    rclpy.try_shutdown()


def measure(kind: str, seconds: float, warmup: float = 3.0) -> dict:
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
    me = [sys.executable, "-m", "coverage_ros.bench.executor"]
    pub = subprocess.Popen(me + ["--role", "publisher", "--seconds", str(seconds + warmup + 4)],
                           env=env, stdout=subprocess.DEVNULL, start_new_session=True)
    try:
        out = subprocess.run(me + ["--role", kind, "--seconds", str(seconds),
                                   "--warmup", str(warmup)], env=env, capture_output=True,
                             text=True, timeout=seconds + warmup + 60, check=True)
    finally:
        pub.send_signal(signal.SIGINT)
        pub.wait(timeout=10)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--role", default="bench",
                    choices=("bench", "publisher", "single", "multi", "events"))
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--warmup", type=float, default=3.0)
    args = ap.parse_args(argv)
    if args.role == "publisher":
        _publisher(args.seconds)
        return 0
    if args.role in ("single", "multi", "events"):
        _listener(args.role, args.warmup, args.seconds)
        return 0
    rows = {}
    for kind in ("single", "multi", "events"):
        print(f"executor {kind}: {args.seconds:g} s ...", file=sys.stderr, flush=True)
        rows[kind] = measure(kind, args.seconds, args.warmup)
        print(f"  {rows[kind]}", file=sys.stderr, flush=True)
    ratio = rows["multi"]["us_per_message"] / max(rows["single"]["us_per_message"], 1e-9)
    events = rows["events"]["us_per_message"] / max(rows["single"]["us_per_message"], 1e-9)
    print(json.dumps({**rows, "multi_over_single": round(ratio, 2),
                      "events_over_single": round(events, 2)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
