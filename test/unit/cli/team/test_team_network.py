"""The launcher's pieces for a team across hosts: robot ids, addresses, the remote command and
the Fast DDS discovery server it starts (no nodes here; integration/test_hosts.py runs the
team)."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest
from rosutil import domain_id

from coverage_ros.cli.team.network import (
    check_reach,
    discovery_advice,
    parse_discovery_address,
    parse_remote_robots,
    remote_command,
    start_discovery_server,
    write_remote_script,
)
from coverage_ros.cli.team.processes import ProcessSet
from coverage_ros.errors import ConfigError


def test_remote_robot_ids_are_checked():
    assert parse_remote_robots(None, 4) == [] and parse_remote_robots("3,1", 4) == [1, 3]
    for text, message in (("1,x", "robot ids separated by commas"), ("4", "out of range 0..3"),
                          ("2,2", "names a robot twice")):
        with pytest.raises(ConfigError, match=message):
            parse_remote_robots(text, 4)


def test_discovery_server_address():
    assert parse_discovery_address("10.0.0.1") == ("10.0.0.1", 11811)
    assert parse_discovery_address("10.0.0.1:7400") == ("10.0.0.1", 7400)
    for text in ("localhost", "10.0.0.1:x", "10.0.0.1:70000", "300.1.1.1"):
        with pytest.raises(ConfigError, match="--discovery-server"):
            parse_discovery_address(text)


def test_remote_robots_need_discovery_beyond_this_host():
    with pytest.raises(ConfigError, match="LOCALHOST"):
        check_reach({}, [2])
    with pytest.raises(ConfigError, match="LOCALHOST"):
        check_reach({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, [2])
    check_reach({}, [])  # nobody remote
    check_reach({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}, [2])
    check_reach({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "10.0.0.2"},
                [2])
    check_reach({}, [2], server=True)


def test_the_remote_command_is_what_to_run_on_the_other_host(tmp_path):
    env = {"ROS_DOMAIN_ID": "142", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "HOME": "/x"}
    cmd = [sys.executable, "-m", "coverage_ros.nodes.robot_node", "--ros-args", "-r",
           "__ns:=/robot_3", "-p", "robot_id:=3", "-p", "strategy_params:={a: 1}"]
    line = remote_command(env, cmd)
    assert line.startswith("export ROS_DOMAIN_ID=142 ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET; ")
    assert "ros2 run coverage_ros robot_node --ros-args -r __ns:=/robot_3 -p robot_id:=3 " \
        "-p 'strategy_params:={a: 1}'" in line
    assert "HOME" not in line
    show = "import os; print(*(os.environ[k] for k in ('ROS_DOMAIN_ID', " \
        "'ROS_AUTOMATIC_DISCOVERY_RANGE')))"
    script = write_remote_script(tmp_path / "remote" / "robot_3.sh", env,
                                 [sys.executable, "-c", show])
    out = subprocess.run(["sh", str(script)], capture_output=True, text=True, check=True,
                         env={"PATH": "/usr/bin:/bin"}).stdout
    assert out.split() == ["142", "SUBNET"]


def udp_port_in_use(port: int) -> bool:
    """Whether a local UDP socket is bound to ``port`` (from /proc/net/udp)."""
    rows = Path("/proc/net/udp").read_text().splitlines()[1:]
    return any(int(row.split()[1].split(":")[1], 16) == port for row in rows)


def test_the_discovery_server_runs_where_asked_and_a_taken_port_is_reported(tmp_path):
    """The wheels' fast-discovery-server, started as the launcher starts it (with nothing of
    the virtual environment on PATH, only the library folders it is given): it runs on the
    address and port asked for, a second one on that port fails at once with the server's
    reason, and SIGINT ends the first cleanly."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    env = {"PATH": "/usr/bin:/bin", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "ROS_DOMAIN_ID": str(domain_id(27))}
    (tmp_path / "first").mkdir()
    (tmp_path / "second").mkdir()
    first, second = ProcessSet(env, tmp_path / "first"), ProcessSet(env, tmp_path / "second")
    try:
        start_discovery_server(first, ("127.0.0.1", port))
        log = first.children["discovery"].log.read_text()
        assert f"UDPv4:[127.0.0.1]:{port}" in log, log
        assert udp_port_in_use(port)
        taken = rf"(?s)127\.0\.0\.1:{port} did not start.*allocate the specified listening port"
        with pytest.raises(RuntimeError, match=taken):
            start_discovery_server(second, ("127.0.0.1", port))
    finally:
        first.stop()
        second.stop()
    assert first.children["discovery"].popen.returncode == 0
    assert not udp_port_in_use(port)


def test_big_teams_with_simple_discovery_are_told_of_the_discovery_server():
    assert discovery_advice(20, server=False) is None
    assert discovery_advice(68, server=True) is None
    text = discovery_advice(68, server=False)
    assert text.startswith("warning: 68 DDS participants (processes) with simple discovery")
    assert "--robots-per-process" in text
    assert "--discovery-server" in text
