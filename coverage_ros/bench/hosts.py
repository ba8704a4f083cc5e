"""Several hosts on one machine: network namespaces joined by veth links and a bridge.

Each "host" is a network namespace of its own with one address on a private subnet
(``10.231.0.<i+1>/24``) and a veth link to a bridge in a further namespace (the "switch"). Only
these namespaces' addresses exist on that subnet: DDS discovery (multicast or a discovery server)
never reaches the machine's real interfaces. Fast DDS keeps to UDP (``FASTDDS_BUILTIN_TRANSPORTS=
UDPv4``): with its default shared-memory transport, processes on one machine would talk past
the network, and the "hosts" would not be apart at all.

:func:`run_across_hosts` runs ``coverage-team`` on host 0 with ``--remote-robots`` and starts
each remote robot on its host from the script the launcher writes (``<out>/remote/``), as a user
would on real machines.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from coverage_ros.bench.environment import REPO, namespace_env

SUBNET = "10.231.0"


@dataclass(frozen=True)
class Host:
    namespace: str
    address: str
    link: str  # its end of the veth pair


@contextlib.contextmanager
def hosts_network(count: int, multicast: bool = True) -> Iterator[list[Host]]:
    """``count`` namespaces ("hosts") on one bridge; yields them, deletes all afterwards (their
    processes must have ended). ``multicast=False``: no multicast route, so simple discovery
    cannot work and only a discovery server can join the hosts."""
    if not 1 <= count <= 8:
        raise ValueError(f"count must be in 1..8, got {count}")
    tag = uuid.uuid4().hex[:6]
    switch = f"cov-sw-{tag}"
    hosts = [Host(f"cov-h{i}-{tag}", f"{SUBNET}.{i + 1}", f"cvh{i}-{tag}") for i in range(count)]
    made: list[str] = []

    def ip(*args: str) -> None:
        subprocess.run(["ip", *args], check=True, capture_output=True, text=True)

    try:
        for ns in [switch] + [h.namespace for h in hosts]:
            ip("netns", "add", ns)
            made.append(ns)
            ip("-n", ns, "link", "set", "lo", "up")
        ip("-n", switch, "link", "add", "br0", "type", "bridge", "mcast_snooping", "0")
        ip("-n", switch, "link", "set", "br0", "up")
        for i, h in enumerate(hosts):
            port = f"cvp{i}-{tag}"
            ip("link", "add", h.link, "type", "veth", "peer", "name", port)
            ip("link", "set", h.link, "netns", h.namespace)
            ip("link", "set", port, "netns", switch)
            ip("-n", switch, "link", "set", port, "master", "br0", "up")
            ip("-n", h.namespace, "addr", "add", f"{h.address}/24", "dev", h.link)
            ip("-n", h.namespace, "link", "set", h.link, "up")
            if multicast:  # simple discovery's multicast leaves through the link
                ip("-n", h.namespace, "route", "add", "224.0.0.0/4", "dev", h.link)
        yield hosts
    finally:
        for ns in reversed(made):  # deleting a namespace deletes its veth ends
            subprocess.run(["ip", "netns", "del", ns], check=False, capture_output=True)


def link_packets(host: Host) -> int:
    """Packets received on ``host``'s link so far (traffic that crossed the 'network')."""
    out = subprocess.run(["ip", "-n", host.namespace, "-j", "-s", "link", "show", host.link],
                         capture_output=True, text=True, check=True).stdout
    return int(json.loads(out)[0]["stats64"]["rx"]["packets"])


@dataclass
class HostsRun:
    summary: dict
    out: Path
    placement: dict[int, str]  # robot id -> namespace it ran in
    packets: dict[str, int]  # namespace -> packets received on its link


def run_across_hosts(hosts: list[Host], out: Path, team_args: list[str], remote: dict[int, int],
                     discovery_server: bool = False, timeout: float = 900) -> HostsRun:
    """``coverage-team`` on ``hosts[0]`` with robots ``remote`` (id -> host index >= 1) started
    on their hosts; simple discovery over the subnet, or a discovery server on host 0."""
    env = namespace_env({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"})
    args = list(team_args) + ["--remote-robots", ",".join(str(r) for r in sorted(remote))]
    if discovery_server:
        args += ["--discovery-server", hosts[0].address]
    exe = str(REPO / ".venv" / "bin" / "coverage-team")
    launcher = subprocess.Popen(
        ["ip", "netns", "exec", hosts[0].namespace, exe, "--quiet", "--out", str(out), *args],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True)
    assert launcher.stderr is not None
    robots: list[subprocess.Popen] = []
    placement = {}
    err_lines: list[str] = []
    try:
        pattern = re.compile(r"coverage-team: start robot (\d+) on its host \((\S+)\):")
        while len(robots) < len(remote):
            line = launcher.stderr.readline()
            if not line:
                raise RuntimeError("coverage-team ended before printing the remote robots:\n"
                                   + "".join(err_lines)[-3000:])
            err_lines.append(line)
            m = pattern.match(line)
            if m is None:
                continue
            rid, script = int(m.group(1)), m.group(2)
            host = hosts[remote[rid]]
            log = open(out / "logs" / f"robot_{rid}.log", "wb")  # noqa: SIM115 - child owns it
            robots.append(subprocess.Popen(
                ["ip", "netns", "exec", host.namespace, "sh", script], env=env, stdout=log,
                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True))
            log.close()
            placement[rid] = host.namespace
        _, err = launcher.communicate(timeout=timeout)
        err_lines.append(err)
    finally:
        for proc in [launcher, *robots]:  # the remote robots outlive the run: stop them
            _stop_group(proc)
    if launcher.returncode != 0:
        raise RuntimeError(f"coverage-team across hosts failed ({launcher.returncode}):\n"
                           + "".join(err_lines)[-3000:])
    summary = json.loads((out / "summary.json").read_text())
    for i in range(len(summary["robots"])):
        placement.setdefault(i, hosts[0].namespace)
    return HostsRun(summary, out, placement, {h.namespace: link_packets(h) for h in hosts})


def _stop_group(proc: subprocess.Popen) -> None:
    for sig, wait in ((signal.SIGINT, 8.0), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0)):
        if proc.poll() is not None:
            return
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, sig)
        deadline = time.monotonic() + wait
        while proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
