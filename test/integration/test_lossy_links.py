"""Lossy links: a team in a network namespace of its own, where nftables drops a random share
of the UDP packets (and Fast DDS is kept off shared memory, so that every message crosses the
filter). The long sweep over 10 / 20 / 40 % against a lossless run is ``scripts/bench_faults``."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from conftest import NO_ESCAPE, shared_map
from rosutil import domain_id

from coverage_ros.bench.environment import (
    have_tools,
    lossy_namespace,
    namespace_env,
    run_team_in,
)
from coverage_ros.cli.plan import main as plan_main

pytestmark = pytest.mark.slow

ECHO = """
import socket
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", 0)); s.settimeout(0.05)
n = 0
for batch in range(20):  # 100 at a time: the socket buffer holds them all
    for k in range(100):
        s.sendto(b"x", s.getsockname())
    while True:
        try:
            s.recv(16); n += 1
        except socket.timeout:
            break
print(n)
"""


def test_the_namespace_drops_the_share_of_udp_packets_asked_for():
    assert have_tools() == ""
    with lossy_namespace(20) as ns:
        got = subprocess.run(["ip", "netns", "exec", ns, sys.executable, "-c", ECHO],
                             capture_output=True, text=True, timeout=120, check=True)
    received = int(got.stdout)
    assert 0.74 * 2000 <= received <= 0.86 * 2000, received  # 80 % +- 6 %
    assert namespace_env()["FASTDDS_BUILTIN_TRANSPORTS"] == "UDPv4"


def test_a_team_still_covers_when_a_fifth_of_its_packets_are_lost(tmp_path):
    sandbox = shared_map("tb3_sandbox")
    plan = tmp_path / "plan.json"
    # (without the closet escape, here and on the team: the test is of the links, and a
    # settled team's pricing of moves would take the robots' update budget)
    assert plan_main(["--map", str(sandbox), "--robots", "4", "--seed", "5", *NO_ESCAPE,
                      "--json", str(plan), "--quiet"]) == 0
    planned = json.loads(plan.read_text())["H"]
    with lossy_namespace(20) as ns:
        summary = run_team_in(ns, tmp_path / "team", [
            "--world", str(sandbox), "--robots", "4", "--duration", "60", "--rtf", "2",
            "--seed", "5", "--no-markers", *NO_ESCAPE, "--domain-id", str(domain_id(8))])
    m = summary["metrics"]
    print(f"20 % loss: H {m['H']:.2f} (start {m['H_start']:.2f}, plan {planned:.2f})")
    assert m["H"] <= 1.3 * planned, (m, planned)
    assert all(r["collisions"] == 0 for r in summary["robots"]), summary["robots"]
