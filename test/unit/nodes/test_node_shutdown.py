"""A node process whose parent has died ends within a bounded time of its SIGTERM, whatever its
clean-up does: the kernel's signal to the child of a killed launcher is the only one it gets.
With its parent alive, a slow clean-up is left to finish (the parent may signal again). One
whose parent dies while it builds its nodes ends at once, even when waiting in native code."""

from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest
from conftest import REPO
from rosutil import domain_id, ros_env

#: A node whose clean-up does not end for a minute: in Python (``sleep``), or in native code
#: that holds the interpreter (libc's ``sleep`` through ``ctypes.PyDLL``, which keeps the GIL).
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

#: A node whose start-up waits 30 s in native code that holds the interpreter and that signals
#: do not end (a mutex locked twice), as a wait on a half-made shared-memory port does.
_STUCK_START = """
import ctypes, sys, time
import rclpy.node
from coverage_ros.nodes import runner

class Deadline(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]

def make():
    node = rclpy.node.Node("stuck_start_probe")
    print("starting", flush=True)
    libc, mutex = ctypes.PyDLL(None), ctypes.create_string_buffer(64)
    libc.pthread_mutex_lock(mutex)
    libc.pthread_mutex_timedlock(mutex, ctypes.byref(Deadline(int(time.time()) + 30, 0)))
    print("built", flush=True)
    return node

sys.exit(runner.run_node("stuck_start_probe", make))
"""

#: The launcher's part: a subreaper (as the launcher is) starts a middle process, which starts
#: the node asking for SIGTERM on its parent's death; the middle one is killed once the node
#: has printed the word given (default "spinning"). The node's exit code and how long it took
#: after that, as JSON.
_ORPHANING = """
import json, os, signal, subprocess, sys, time
from coverage_ros.nodes.preloaded import PR_SET_CHILD_SUBREAPER, prctl
log, stuck, node = sys.argv[1], sys.argv[2], sys.argv[3]
ready = sys.argv[4] if len(sys.argv) > 4 else "spinning"
middle = '''
import signal, subprocess, sys
from coverage_ros.nodes.preloaded import PR_SET_PDEATHSIG, prctl
with open(sys.argv[1], "w") as out:
    node = subprocess.Popen([sys.executable, "-c", sys.argv[3], sys.argv[2]], stdout=out,
                            stderr=out, preexec_fn=lambda: prctl(PR_SET_PDEATHSIG, signal.SIGTERM))
print(node.pid, flush=True)
node.wait()
'''
assert prctl(PR_SET_CHILD_SUBREAPER, 1)
proc = subprocess.Popen([sys.executable, "-c", middle, log, stuck, node], stdout=subprocess.PIPE)
pid = int(proc.stdout.readline())
deadline = time.monotonic() + 60.0
while ready not in open(log).read():
    assert time.monotonic() < deadline, open(log).read()
    time.sleep(0.05)
proc.kill()
proc.wait()
t = time.monotonic()
_, status = os.waitpid(pid, 0)
print(json.dumps({"code": os.waitstatus_to_exitcode(status), "took": time.monotonic() - t}))
"""


@pytest.mark.parametrize("stuck, returncode", [("python", 128 + signal.SIGTERM),
                                               ("native", -signal.SIGALRM)])
def test_an_orphans_clean_up_that_never_ends_is_cut_short(tmp_path, stuck, returncode):
    log = tmp_path / "node.log"
    out = subprocess.run([sys.executable, "-c", _ORPHANING, str(log), stuck, _STUCK_NODE],
                         cwd=REPO, env=ros_env(domain_id(11)), capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert result["code"] == returncode, log.read_text()
    # the limit of 1 s from the signal (the timer: 128 + SIGTERM), or that plus the backstop
    # (the kernel's SIGALRM); the upper bound only says it was bounded
    assert (0.9 if stuck == "python" else 2.9) < result["took"] < 15.0, result
    text = log.read_text()
    assert "cleaning up" in text
    assert ("ending now" in text) == (stuck == "python"), text


def test_with_its_parent_alive_a_slow_clean_up_is_left_to_finish():
    """Past the limit and the backstop the node is still cleaning up; the second signal ends it
    at once, as a live launcher's SIGTERM after its SIGINT does."""
    proc = subprocess.Popen([sys.executable, "-c", _STUCK_NODE, "python"], cwd=REPO, text=True,
                            env=ros_env(domain_id(11)), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "spinning"
        proc.send_signal(signal.SIGINT)
        assert proc.stdout.readline().strip() == "cleaning up"
        with pytest.raises(subprocess.TimeoutExpired):
            proc.wait(timeout=4.0)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 128 + signal.SIGTERM
    finally:
        proc.kill()
        proc.wait()


def test_a_clean_up_that_ends_leaves_no_deadline_behind(tmp_path):
    """An orphan's run_node returns after a quick clean-up: the timer and the alarm are called
    off, the interpreter goes on (4 s, past the limit and the backstop) and exits with 0."""
    node = _STUCK_NODE.replace("time.sleep(60)", "pass")
    node = node.replace("sys.exit(runner.run_node(", "code = (runner.run_node(")
    node += "time.sleep(4.0)\nprint('still here', code, flush=True)\n"
    log = tmp_path / "node.log"
    out = subprocess.run([sys.executable, "-c", _ORPHANING, str(log), "python", node],
                         cwd=REPO, env=ros_env(domain_id(11)), capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["code"] == 0, log.read_text()
    assert "still here 0" in log.read_text()


def test_an_orphan_whose_start_up_waits_in_native_code_ends_at_once(tmp_path):
    """The parent dies while the node's start-up waits where no Python signal handler can run:
    the kernel ends it (SIGKILL, asked for while the nodes are built) instead of the SIGTERM
    handler 30 s later, when the wait gives up."""
    log = tmp_path / "node.log"
    out = subprocess.run([sys.executable, "-c", _ORPHANING, str(log), "native", _STUCK_START,
                          "starting"],
                         cwd=REPO, env=ros_env(domain_id(11)), capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert result["code"] == -signal.SIGKILL, log.read_text()
    assert result["took"] < 10.0, result
    assert "built" not in log.read_text()
