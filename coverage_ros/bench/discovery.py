"""How long DDS discovery takes for a big team (``scripts/bench_discovery``): N processes, each
one ROS participant with one node that publishes and subscribes one shared topic (as every robot
does with its neighbours), started together; each notes the moment its ROS graph holds all N
nodes. Run with simple discovery (multicast on this machine) and with the Fast DDS discovery
server (``coverage-team --discovery-server``: ``ROS_DISCOVERY_SERVER`` and
``ROS_SUPER_CLIENT=TRUE``, the server a child of this harness).

Figures per mode: ``complete`` - participants that saw all N nodes within ``TIMEOUT``
(``fewest_seen``: the poorest one's count); ``after_all_ready_s`` - from the moment the last
participant had its node up until the last one saw everyone (None unless all did);
``all_ready_s`` - from the first start until the last node was up (Python, rclpy and the
participant's start on two cores, the same in both modes); ``cpu_s`` - CPU seconds of all
participants by then. Each mode runs on its own locked, unused domain id.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TIMEOUT = 90.0  # [s] a participant waits to see everyone
POLL = 0.1  # [s] graph polling of a participant


def participant(index: int, expect: int) -> int:
    """One participant: prints ``seen <unix time>`` once its graph holds ``expect`` nodes, then
    stays until SIGINT / SIGTERM / stdin closing."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from std_msgs.msg import Empty

    rclpy.init()
    node = rclpy.create_node(f"probe_{index}")
    node.create_publisher(Empty, "/discovery_probe", 10)
    node.create_subscription(Empty, "/discovery_probe", lambda _msg: None, 10)
    print(f"ready {time.time():.6f}", flush=True)
    deadline = time.monotonic() + TIMEOUT
    try:
        while (seen := len(node.get_node_names())) < expect and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=POLL)
        print(f"seen {time.time():.6f} {seen}", flush=True)
        sys.stdin.read()  # until the harness closes it (or a signal ends the process)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def _cpu_seconds(pid: int) -> float:
    import psutil

    try:
        t = psutil.Process(pid).cpu_times()
        return t.user + t.system
    except psutil.Error:
        return 0.0


def measure(n: int, server: bool, say) -> dict:
    from coverage_ros.cli.team.domains import acquire_domain
    from coverage_ros.cli.team.network import start_discovery_server
    from coverage_ros.cli.team.processes import ProcessSet
    from coverage_ros.viz.web_viewer import free_ports

    lock = acquire_domain(None)
    env = {**os.environ, "ROS_DOMAIN_ID": str(lock.domain_id),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    folder = Path(tempfile.mkdtemp(prefix="bench_discovery_"))
    procs = ProcessSet(env, folder)
    children: list[subprocess.Popen] = []
    try:
        if server:
            port = free_ports(1)[0]
            start_discovery_server(procs, ("127.0.0.1", port))
            env.update(ROS_DISCOVERY_SERVER=f"127.0.0.1:{port}", ROS_SUPER_CLIENT="TRUE")
        t0 = time.time()
        for i in range(n):
            children.append(subprocess.Popen(
                [sys.executable, "-m", "coverage_ros.bench.discovery", "--participant", str(i),
                 "--expect", str(n)], env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL, text=True, start_new_session=True))
        lines = _two_lines_each(children, t0 + TIMEOUT + 150.0)
        ready, seen, counts = [], [], []
        for k, got in enumerate(lines):
            words = [line.split() for line in got]
            if len(words) < 2 or words[0][0] != "ready" or words[1][0] != "seen":
                raise RuntimeError(f"participant {k} said {got}, expected 'ready ...' and "
                                   "'seen ...'")
            ready.append(float(words[0][1]))
            seen.append(float(words[1][1]))
            counts.append(int(words[1][2]))
        cpu = sum(_cpu_seconds(c.pid) for c in children)
        complete = sum(c >= n for c in counts)
        row = {"participants": n, "complete": complete, "fewest_seen": min(counts),
               "all_ready_s": round(max(ready) - t0, 2),
               "after_all_ready_s": round(max(seen) - max(ready), 2) if complete == n else None,
               "cpu_s": round(cpu, 1)}
        what = (f"saw each other {row['after_all_ready_s']} s after the last came up"
                if complete == n else f"only {complete} saw all within {TIMEOUT:g} s (the "
                f"poorest saw {min(counts)} nodes)")
        say(f"  {'server' if server else 'simple'}: {n} participants (all up after "
            f"{row['all_ready_s']} s) {what}; {row['cpu_s']} CPU s")
        return row
    finally:
        for child in children:
            _signal_group(child, signal.SIGINT)
        deadline = time.monotonic() + 15.0
        for child in children:
            try:
                child.wait(timeout=max(deadline - time.monotonic(), 0.1))
            except subprocess.TimeoutExpired:
                _signal_group(child, signal.SIGKILL)
                child.wait()
        procs.stop()
        lock.release()


def _signal_group(child: subprocess.Popen, sig: int) -> None:
    """Signal the process group this harness created for ``child`` (nothing else)."""
    if child.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(child.pid, sig)


def _two_lines_each(children: list[subprocess.Popen], deadline: float) -> list[list[str]]:
    """The first two lines of every child's output (fewer for one that fell silent by
    ``deadline``), read on one thread per child."""
    import threading

    lines: list[list[str]] = [[] for _ in children]

    def read(k: int) -> None:
        out = children[k].stdout
        assert out is not None
        for _ in range(2):
            line = out.readline()
            if not line:
                return
            lines[k].append(line)

    threads = [threading.Thread(target=read, args=(k,), daemon=True)
               for k in range(len(children))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(max(deadline - time.time(), 0.0))
    return [list(x) for x in lines]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--participants", type=int, nargs="+", default=[16, 64])
    ap.add_argument("--participant", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--expect", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.participant is not None:
        return participant(args.participant, args.expect)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

    def say(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    rows = []
    for n in args.participants:
        say(f"discovery of {n} participants (one process each) ...")
        simple = measure(n, False, say)
        served = measure(n, True, say)
        rows.append({"participants": n, "simple": simple, "server": served})
    print(json.dumps({"discovery": rows}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
