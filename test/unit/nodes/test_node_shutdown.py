"""A node process ends within a bounded time of its first SIGTERM, whatever its clean-up does:
a process whose launcher was killed gets no second signal to cut a slow shutdown short."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest
from conftest import REPO
from rosutil import domain_id, ros_env

#: A node whose clean-up never ends: in Python (``sleep``), or in native code that holds the
#: interpreter (libc's ``sleep`` through ``ctypes.PyDLL``, which keeps the GIL).
_STUCK_NODE = """
import ctypes, sys, time
import rclpy.node
from coverage_ros.nodes import runner

runner.SHUTDOWN_LIMIT, runner.SHUTDOWN_BACKSTOP = 1.0, 2.0
holds_the_interpreter = sys.argv[1] == "native"

def make():
    node = rclpy.node.Node("stuck_probe")
    up = node.create_timer(0.05, lambda: (print("spinning", flush=True), up.cancel()))
    return node

def cleanup(node):
    print("cleaning up", flush=True)
    if holds_the_interpreter:
        ctypes.PyDLL(None).sleep(60)
    time.sleep(60)

sys.exit(runner.run_node("stuck_probe", make, cleanup=cleanup))
"""


@pytest.mark.parametrize("stuck, returncode", [("python", 128 + signal.SIGTERM),
                                               ("native", -signal.SIGALRM)])
def test_a_clean_up_that_never_ends_is_cut_short(stuck, returncode):
    proc = subprocess.Popen([sys.executable, "-c", _STUCK_NODE, stuck], cwd=REPO, text=True,
                            env=ros_env(domain_id(11)), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "spinning", proc.stderr
        proc.send_signal(signal.SIGTERM)
        assert proc.stdout.readline().strip() == "cleaning up"
        signalled = time.monotonic()
        assert proc.wait(timeout=30) == returncode
        took = time.monotonic() - signalled
    finally:
        proc.kill()
        proc.wait()
    # the limit of 1 s from the signal (the timer: 128 + SIGTERM), or that plus the backstop
    # (the kernel's SIGALRM); the upper bound only says it was bounded
    assert (0.9 if stuck == "python" else 2.9) < took < 15.0, took
    stderr = proc.stderr.read() if proc.stderr else ""
    assert ("ending now" in stderr) == (stuck == "python"), stderr


def test_a_clean_up_that_ends_leaves_no_deadline_behind():
    """run_node returns after a quick clean-up: the timer and the alarm are called off, the
    interpreter goes on (here 4 s, past the limit and the backstop) and exits with 0."""
    script = _STUCK_NODE.replace("time.sleep(60)", "pass") + "\n"
    script = script.replace("sys.exit(runner.run_node(", "code = (runner.run_node(")
    script += "time.sleep(4.0)\nprint('still here', code, flush=True)\n"
    proc = subprocess.Popen([sys.executable, "-c", script, "python"], cwd=REPO, text=True,
                            env=ros_env(domain_id(11)), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "spinning"
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == 0, err
    assert out.split() == ["cleaning", "up", "still", "here", "0"], out
