"""Malformed messages on every topic the team's nodes subscribe to, from hypothesis.

A small live team - the world node (3 robots on the empty world), robot 0 (pose from ground
truth, lidar on), robot 1 (pose from /tf), robot 2 (exploring: no map, shares evidence), the
rerun bridge (recording) and the marker node, each its own process as ``coverage-team`` starts
them - gets the messages of ``bench/fuzz_messages.py`` on each topic of its ``TOPICS`` table.
Afterwards (:meth:`FuzzTeam.check`) every node must still run and hold its last good state: each
robot's state follows the simulator's pose, the world still has exactly its three robots, no
region of interest appeared, the marker node still shows every robot, the bridge still records
(checked by reading the recording back) - and the warnings were throttled (no more than one per
kind of problem every ``WARN_PERIOD``).
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import math
import os
import re
import signal
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from hypothesis import HealthCheck, Phase, given, settings

from coverage_ros.bench.fuzz_messages import TOPICS, Target
from coverage_ros.cli.team.processes import ProcessSet, executable, ros_args
from coverage_ros.nodes.robot_graph import robot_topics

STARTS = "1.5,1.5,0.0;6.5,1.5,3.14;4.0,6.5,-1.57"  # the empty world is 8 m x 8 m
ROBOTS: dict[int, dict[str, object]] = {0: {}, 1: {"pose_source": "tf"}, 2: {"explore": True}}
READY_TIMEOUT = 90.0  # [s] wall: every robot has made an update, every topic has its listeners
#: Warnings of one kind closer together than this count as not throttled (the nodes' throttle
#: periods are 2 s (world) and 5 s; log stamps come from different clocks, hence the margin).
WARN_GAP = 1.5
NUMBER = re.compile(r"-?\d+\.\d*(e[-+]?\d+)?|-?\d{3,}|\bnan\b|\binf\b")  # not robot ids
WARN_LINE = re.compile(r"^\[WARN\] \[(\d+\.\d+)\] \[([^\]]+)\]: (.*)$")


@dataclass
class FuzzReport:
    messages: int = 0
    per_topic: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    node_crashes: int = 0
    warnings: dict[str, int] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)

    def as_json(self) -> dict:
        return {"messages": self.messages, "topics": len(self.per_topic),
                "node_crashes": self.node_crashes, "seconds": round(self.seconds, 1),
                "warnings": self.warnings, "problems": self.problems}


class FuzzTeam:
    """The team as separate processes (logs in ``folder``) plus a client node in this process
    that publishes on every target topic. Use as a context manager."""

    def __init__(self, folder: Path, domain: int) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.folder, self.domain = folder, domain
        env = dict(os.environ)
        env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        env.update(ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")
        os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        folder.mkdir(parents=True, exist_ok=True)
        self.procs = ProcessSet(env, folder)
        self.rrd = folder / "fuzz.rrd"
        for rid, extra in ROBOTS.items():
            self.procs.start(f"robot_{rid}", executable("robot_node") + ros_args(
                f"/robot_{rid}", robot_id=rid, use_sim_time=True, world="empty", **extra))
        self.procs.start("world", executable("world_node") + ros_args(
            world="empty", num_robots=len(ROBOTS), starts=STARTS, seed=1, status_rate_hz=2.0))
        self.procs.start("bridge", executable("rerun_bridge") + ros_args(
            record_path=str(self.rrd), world="empty", use_sim_time=True))
        self.procs.start("markers", executable("marker_node") + ros_args(use_sim_time=True))
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("fuzzer", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.pubs = {t.topic: self._publisher(t) for t in TOPICS}
        self.truth: dict[int, tuple] = {}
        self.states: dict[int, tuple[float, dict]] = {}
        self.markers: list = []
        self._listen()

    # ------------------------------------------------------------------ plumbing
    def _publisher(self, target: Target):
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from coverage_ros.bench.fuzz_messages import message_type

        qos = QoSProfile(depth=10)
        if target.qos == "latched":
            qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        elif target.qos == "best_effort":
            qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        return self.node.create_publisher(message_type(target.type_name), target.topic, qos)

    def _listen(self) -> None:
        from coverage_msgs.msg import RobotState
        from nav_msgs.msg import Odometry
        from visualization_msgs.msg import MarkerArray

        from coverage_ros.nodes import conversions as conv

        def on_state(rid: int, msg) -> None:
            # The fuzzer's own (always malformed) states on robot 1's topic are skipped.
            with contextlib.suppress(ValueError):
                self.states[rid] = (time.monotonic(), conv.coverage_state_values(msg))

        def on_truth(rid: int, msg: Odometry) -> None:
            self.truth[rid] = (time.monotonic(), msg)

        for rid in ROBOTS:
            self.node.create_subscription(Odometry, f"/robot_{rid}/ground_truth",
                                          functools.partial(on_truth, rid), 10)
            self.node.create_subscription(RobotState, f"/robot_{rid}/coverage_state",
                                          functools.partial(on_state, rid), 10)
        self.node.create_subscription(MarkerArray, "/coverage/markers", self.markers.append, 10)

    def spin(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)

    def dead(self) -> list[str]:
        return [name for name, child in self.procs.children.items() if not child.alive]

    def __enter__(self) -> FuzzTeam:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        import rclpy

        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.procs.stop()

    # ------------------------------------------------------------------ phases
    def wait_ready(self, timeout: float = READY_TIMEOUT) -> None:
        """Until every robot published a state with its first update's mass, and every target
        topic has as many subscribers as nodes listen on it (RuntimeError naming what is not)."""
        deadline = time.monotonic() + timeout
        while True:
            self.spin(0.2)
            if self.dead():
                raise RuntimeError(f"{self.dead()} exited during start-up:\n{self._tails()}")
            updated = {r for r, (_, v) in self.states.items() if "mass" in v}
            short = {t.topic: (self.pubs[t.topic].get_subscription_count(), len(t.nodes))
                     for t in TOPICS
                     if self.pubs[t.topic].get_subscription_count() < len(t.nodes)}
            if updated == set(ROBOTS) and not short:
                return
            if time.monotonic() > deadline:
                raise RuntimeError(f"not ready after {timeout:g} s: robots updated "
                                   f"{sorted(updated)}, topics without all their listeners "
                                   f"(have, want): {short}")

    def fuzz(self, examples: int, report: FuzzReport, say=None) -> None:
        """``examples`` hypothesis examples per target topic, published one by one; stops at
        the first node that dies (AssertionError naming it and the topic)."""
        t0 = time.monotonic()
        for target in TOPICS:
            sent = self._fuzz_one(target, examples, report)
            report.per_topic[target.topic] = sent
            report.messages += sent
            if say is not None:
                say(f"  {target.topic}: {sent} messages, every node alive")
        report.seconds = time.monotonic() - t0

    def _fuzz_one(self, target: Target, examples: int, report: FuzzReport) -> int:
        sent = 0
        pub = self.pubs[target.topic]

        @settings(max_examples=examples, deadline=None, database=None, derandomize=True,
                  phases=[Phase.generate], suppress_health_check=list(HealthCheck))
        @given(target.strategy())
        def send(msg) -> None:
            nonlocal sent
            pub.publish(msg)
            sent += 1
            self.spin(0.01)
            dead = self.dead()
            if dead:
                report.node_crashes = len(dead)
                raise AssertionError(f"{dead} died after {sent} messages on {target.topic} "
                                     f"(last: {str(msg)[:300]}):\n{self._tails()}")

        send()
        return sent

    def check(self, report: FuzzReport, settle: float = 4.0) -> None:
        """After the fuzz: the team's last good state holds (see the module docstring); what
        does not goes to ``report.problems``."""
        from coverage_ros.nodes import conversions as conv

        end = time.monotonic()
        self.spin(settle)
        problems = report.problems
        if self.dead():
            report.node_crashes = len(self.dead())
            problems.append(f"{self.dead()} died:\n{self._tails()}")
            return
        for rid in ROBOTS:
            got, truth = self.states.get(rid), self.truth.get(rid)
            if got is None or got[0] < end or truth is None or truth[0] < end:
                problems.append(f"robot {rid}: no state or ground truth after the fuzz")
                continue
            x, y, _ = conv.odometry_to_pose(truth[1])
            off = math.hypot(got[1]["x"] - x, got[1]["y"] - y)
            if not off < 0.35:
                problems.append(f"robot {rid}: state at ({got[1]['x']:.2f}, {got[1]['y']:.2f}), "
                                f"simulator at ({x:.2f}, {y:.2f})")
        ids = {rid for rid, name in robot_topics(self.node.get_topic_names_and_types(),
                                                 "robot_", "ground_truth")
               if self.node.count_publishers(name) > 0}
        if ids != set(ROBOTS):
            problems.append(f"the world's robots are {sorted(ids)}, expected {sorted(ROBOTS)}")
        for rid in ROBOTS:
            log = self.procs.children[f"robot_{rid}"].log.read_text(errors="replace")
            if "region of interest now" in log:
                problems.append(f"robot {rid} took a region of interest from the fuzz")
        shown = set()
        for array in self.markers[-3:]:
            shown |= {m.id for m in array.markers if m.ns == "cell" and m.action == m.ADD}
        if not set(ROBOTS) <= shown:
            problems.append(f"the marker node's last arrays show cells of {sorted(shown)}")
        report.warnings, bursts = self._warnings()
        problems += bursts

    def stop_bridge_and_read(self, report: FuzzReport, after_sim: float) -> None:
        """SIGINT to the bridge; its recording must be complete and hold robot poses logged
        after sim time ``after_sim``."""
        from rerun.chunk import RrdReader

        self.procs.signal("bridge", signal.SIGINT)
        code = self.procs.children["bridge"].popen.wait(timeout=30)
        if code != 0:
            report.problems.append(f"the bridge exited with {code}")
            return
        latest = -math.inf
        for chunk in RrdReader(self.rrd).store().stream():
            if chunk.entity_path == "/world/robots":
                batch = chunk.to_record_batch()
                if "sim_time" in batch.schema.names:
                    times = batch.column("sim_time").cast("int64").to_pylist()
                    latest = max([latest] + [t * 1e-9 for t in times if t is not None])
        if not latest > after_sim:
            report.problems.append(f"the recording's last robot poses are at sim time "
                                   f"{latest:.1f} s, not after {after_sim:.1f} s")

    def sim_time(self) -> float:
        from rosgraph_msgs.msg import Clock

        got: list = []
        sub = self.node.create_subscription(Clock, "/clock", got.append, 10)
        deadline = time.monotonic() + 10
        while not got and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        self.node.destroy_subscription(sub)
        return got[-1].clock.sec + got[-1].clock.nanosec * 1e-9 if got else math.nan

    # ------------------------------------------------------------------ logs
    def _tails(self) -> str:
        return "\n".join(f"--- {c.name}:\n{self.procs.tail(c, 15)}"
                         for c in self.procs.children.values())

    def _warnings(self) -> tuple[dict[str, int], list[str]]:
        """Warning counts per node, and kinds of warning repeated faster than the throttle."""
        counts, bursts = {}, []
        for name, child in self.procs.children.items():
            seen: dict[str, list[float]] = defaultdict(list)
            for line in child.log.read_text(errors="replace").splitlines():
                m = WARN_LINE.match(line)
                if m:
                    kind = " ".join(NUMBER.sub("#", m.group(3)).split()[:6])
                    seen[kind].append(float(m.group(1)))
            counts[name] = sum(len(v) for v in seen.values())
            for kind, stamps in seen.items():
                gaps = [b - a for a, b in itertools.pairwise(stamps)]
                if gaps and min(gaps) < WARN_GAP:
                    bursts.append(f"{name}: '{kind}' logged {len(stamps)} times, "
                                  f"{min(gaps):.2f} s apart at the closest")
        return counts, bursts


def fuzz_section(examples: int, folder: Path, say) -> dict:
    """``scripts/bench_faults`` part: the whole table, ``examples`` messages per topic."""
    from coverage_ros.cli.team.domains import acquire_domain

    lock = acquire_domain(None)
    report = FuzzReport()
    try:
        say(f"fuzz: {examples} malformed messages on each of {len(TOPICS)} topics ...")
        with FuzzTeam(folder / "fuzz", lock.domain_id) as team:
            team.wait_ready()
            try:
                team.fuzz(examples, report, say)
            except AssertionError as exc:
                report.problems.append(str(exc))
            else:
                sim = team.sim_time()
                team.check(report)
                team.stop_bridge_and_read(report, sim)
    finally:
        lock.release()
    for problem in report.problems:
        say(f"  problem: {problem}")
    return report.as_json()
