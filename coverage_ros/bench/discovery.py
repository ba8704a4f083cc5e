"""How long DDS discovery takes for a big team (``scripts/bench_discovery``): N processes, each
one ROS participant with one node that publishes and subscribes one shared topic (as every robot
does with its neighbours), started together; each notes the moment its ROS graph holds all N
nodes. Run with simple discovery (multicast on this machine) and with the Fast DDS discovery
server (``coverage-team --discovery-server``: ``ROS_DISCOVERY_SERVER`` and
``ROS_SUPER_CLIENT=TRUE``, the server a child of this harness).

Figures per mode: ``all_seen_s`` - from the first start until the last participant saw
everyone; ``after_last_start_s`` - from the moment the last one was started; ``start_s`` - how
long starting the N processes took (rclpy's import and init, the same in both modes); the CPU
seconds all participants spent until then (``cpu_s``). Each mode runs on its own locked,
unused domain id.
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

TIMEOUT = 240.0  # [s] for one mode to finish discovery
POLL = 0.02  # [s] graph polling of a participant


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
    try:
        while len(node.get_node_names()) < expect:
            rclpy.spin_once(node, timeout_sec=POLL)
        print(f"seen {time.time():.6f}", flush=True)
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
    from coverage_ros.cli.domains import acquire_domain
    from coverage_ros.cli.processes import ProcessSet
    from coverage_ros.cli.team_network import start_discovery_server
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
        t_last = time.time()
        seen = []
        for k, child in enumerate(children):
            line = _read_line(child, t0 + TIMEOUT)
            if not line.startswith("seen "):
                raise RuntimeError(f"participant {k} did not see all {n} nodes within "
                                   f"{TIMEOUT:g} s ({line.strip() or 'no output'})")
            seen.append(float(line.split()[1]))
        cpu = sum(_cpu_seconds(c.pid) for c in children)
        row = {"participants": n, "all_seen_s": round(max(seen) - t0, 2),
               "after_last_start_s": round(max(seen) - t_last, 2),
               "start_s": round(t_last - t0, 2), "cpu_s": round(cpu, 1)}
        say(f"  {'server' if server else 'simple'}: {n} participants saw each other "
            f"{row['all_seen_s']} s after the first start ({row['after_last_start_s']} s after "
            f"the last; starting them took {row['start_s']} s), {row['cpu_s']} CPU s")
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


def _read_line(child: subprocess.Popen, deadline: float) -> str:
    import select

    while time.time() < deadline:
        ready, _, _ = select.select([child.stdout], [], [], 0.5)
        if ready:
            return child.stdout.readline()
        if child.poll() is not None:
            return ""
    return ""


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
        rows.append({"participants": n, "simple": simple, "server": served,
                     "server_over_simple": round(served["after_last_start_s"]
                                                 / max(simple["after_last_start_s"], 1e-3), 2)})
    print(json.dumps({"discovery": rows}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
