"""Helpers for integration tests: node processes on a private DDS domain, and a plain rclpy
client in the test process with waits that always time out.

Every process gets ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (unless the caller set another
value) and the test's own ``ROS_DOMAIN_ID``: ``COVERAGE_ROS_TEST_DOMAIN_BASE`` (set per run by
scripts/test, 100..199) plus an offset per test module and pytest-xdist worker (or slot), taken
among the ids the launcher never draws as fresh ones: a team started without ``--domain-id``
(the startup and fuzz benches' short versions) runs beside the other tests and would otherwise
join one of their domains whenever its probe ran before that test's nodes were up.
"""

from __future__ import annotations

import contextlib
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from coverage_ros.cli.team.domains import FRESH_RANGE, MAX_DOMAIN_ID

REPO = Path(__file__).resolve().parents[1]
_FALLBACK_BASE = random.randint(100, 199)  # one per test process when scripts/test set none
# 1..232 without the launcher's fresh range (0 is every ROS 2 tool's default): 132 ids
TEST_DOMAINS = tuple(d for d in range(1, MAX_DOMAIN_ID + 1)
                     if not FRESH_RANGE[0] <= d <= FRESH_RANGE[1])


def domain_id(offset: int) -> int:
    """A DDS domain id for this run, test ``offset`` (0..29) and slot: the xdist worker, or
    ``COVERAGE_ROS_TEST_DOMAIN_SLOT`` for a pytest run beside other runs of the same base
    (scripts/test's real-time tests beside its xdist workers). The 132 test ids hold four slots
    of 30, and none of them is one the launcher may pick for a team of its own."""
    base = int(os.environ.get("COVERAGE_ROS_TEST_DOMAIN_BASE", _FALLBACK_BASE))
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    wid = int(worker[2:]) if worker[2:].isdigit() else 0
    wid = int(os.environ.get("COVERAGE_ROS_TEST_DOMAIN_SLOT", wid))
    return TEST_DOMAINS[(base + offset + 30 * wid) % len(TEST_DOMAINS)]


def ros_env(domain: int, **extra: str) -> dict[str, str]:
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env["ROS_DOMAIN_ID"] = str(domain)
    env["PYTHONUNBUFFERED"] = "1"
    env.update(extra)
    return env


class NodeProcess:
    """A node in its own process group; output goes to a temporary log file.

    Use as a context manager: leaving it stops the whole group (SIGINT, then SIGTERM, then
    SIGKILL), so nothing outlives the test.
    """

    def __init__(self, cmd: list[str], domain: int, env: dict[str, str] | None = None) -> None:
        self.cmd = cmd
        self.log = tempfile.NamedTemporaryFile(  # noqa: SIM115 - closed in __exit__
            prefix="node-", suffix=".log", delete=False)
        self.proc = subprocess.Popen(cmd, cwd=REPO, env=env or ros_env(domain),
                                     stdin=subprocess.DEVNULL, stdout=self.log,
                                     stderr=subprocess.STDOUT, start_new_session=True)

    @classmethod
    def world_node(cls, domain: int, *params: str, exe: str | None = None) -> NodeProcess:
        """Start the world node with ``-p name:=value`` parameters."""
        cmd = [exe] if exe else [sys.executable, "-m", "coverage_ros.nodes.world_node"]
        args = ["--ros-args"] + [a for p in params for a in ("-p", p)]
        return cls(cmd + args, domain)

    def output(self) -> str:
        return Path(self.log.name).read_text(errors="replace")

    def alive(self) -> bool:
        return self.proc.poll() is None

    def signal(self, sig: int) -> None:
        if self.alive():
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, sig)

    def stop(self, timeout: float = 5.0) -> int:
        """Stop the process group; returns the exit code."""
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            self.signal(sig)
            try:
                return self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                continue
        return self.proc.wait()

    def __enter__(self) -> NodeProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
        # Children of the group (none expected) must not outlive the test either.
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.proc.pid, signal.SIGKILL)
        self.log.close()
        with contextlib.suppress(OSError):
            os.unlink(self.log.name)


class RosClient:
    """An rclpy node in the test process on its own context and domain."""

    def __init__(self, domain: int, name: str = "test_client") -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        from coverage_ros.nodes.shm_ports import remove_broken_ports

        os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        remove_broken_ports()  # (a test that killed a process may have left one)
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def subscribe(self, topic: str, msg_type: Any, qos: Any = 10) -> list:
        """Collect every message of ``topic`` into the returned list (while spinning)."""
        received: list = []
        self.node.create_subscription(msg_type, topic, received.append, qos)
        return received

    def publisher(self, topic: str, msg_type: Any, qos: Any = 10):
        return self.node.create_publisher(msg_type, topic, qos)

    def spin_until(self, condition: Callable[[], bool], timeout: float, what: str = "") -> None:
        """Spin until ``condition()`` holds; TimeoutError naming ``what`` after ``timeout``."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise TimeoutError(f"timed out after {timeout:g} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.05)

    def spin_for(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def wait_for(self, topic: str, msg_type: Any, predicate: Callable[[Any], bool] | None = None,
                 timeout: float = 30.0, qos: Any = 10) -> Any:
        """The first message on ``topic`` satisfying ``predicate`` (a fresh subscription, whose
        discovery is part of the wait: ``timeout`` [s] is a safety net for a loaded machine)."""
        hits: list = []

        def on_msg(msg: Any) -> None:
            if predicate is None or predicate(msg):
                hits.append(msg)

        sub = self.node.create_subscription(msg_type, topic, on_msg, qos)
        try:
            self.spin_until(lambda: bool(hits), timeout, f"a message on {topic}")
        finally:
            self.node.destroy_subscription(sub)
        return hits[0]

    def close(self) -> None:
        import rclpy

        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def spin_until_exit(client: RosClient, proc: subprocess.Popen, timeout: float) -> str:
    """Spin ``client`` while ``proc`` (a launcher started with ``start_new_session``) runs, at
    most ``timeout`` s; its stderr. A process group that outlives that is killed."""
    deadline = time.monotonic() + timeout
    try:
        while proc.poll() is None and time.monotonic() < deadline:
            client.spin_for(0.2)
        return proc.communicate(timeout=30)[1]
    finally:
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
