"""A team across several hosts: robots whose processes run on other machines
(``--remote-robots``) and the Fast DDS discovery server (``--discovery-server``).

The launcher's host runs the world node (and any local robots); for a remote robot it prints the
exact command to run on its host - the environment to export and the ``ros2 run`` line - and
waits for that robot to join. DDS discovery must then reach beyond this host: simple discovery
with ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`` (or ``ROS_STATIC_PEERS``), or a discovery server
that every process names in ``ROS_DISCOVERY_SERVER``, each a "super client"
(``ROS_SUPER_CLIENT=TRUE``: a plain client learns only of the topics it uses, and robots find
their neighbours in the ROS graph). A team that asks for remote robots while
discovery stays on this host is refused before anything starts.
"""

from __future__ import annotations

import ipaddress
import os
import shlex
import shutil
import sys
import sysconfig
import time
from pathlib import Path

from coverage_ros.errors import ConfigError

DEFAULT_DISCOVERY_PORT = 11811  # Fast DDS's default for a discovery server
DISCOVERY_START_TIMEOUT = 10.0  # [s] wall time for the server to say it runs
#: Environment a remote robot needs besides ROS_DOMAIN_ID (when set on the launcher's host).
FORWARDED_ENV = ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS", "ROS_DISCOVERY_SERVER",
                 "ROS_SUPER_CLIENT", "RMW_IMPLEMENTATION", "FASTDDS_BUILTIN_TRANSPORTS",
                 "COVERAGE_ROS_EXECUTOR")


def parse_remote_robots(text: str | None, n: int) -> list[int]:
    """``--remote-robots 2,3`` -> ``[2, 3]`` (ids of the team, each once)."""
    if not text:
        return []
    try:
        ids = [int(part) for part in text.split(",")]
    except ValueError:
        raise ConfigError.at("--remote-robots", "must be robot ids separated by commas",
                             text, "e.g. 2,3") from None
    bad = [i for i in ids if not 0 <= i < n]
    if bad:
        raise ConfigError.at("--remote-robots", f"robot id out of range 0..{n - 1}", bad)
    if len(set(ids)) != len(ids):
        raise ConfigError.at("--remote-robots", "names a robot twice", text)
    return sorted(ids)


def parse_discovery_address(text: str) -> tuple[str, int]:
    """``ADDRESS[:PORT]`` of the discovery server to run (an IPv4 address of this host)."""
    host, _, port_text = text.partition(":")
    try:
        ipaddress.IPv4Address(host)
        port = int(port_text) if port_text else DEFAULT_DISCOVERY_PORT
    except ValueError:
        raise ConfigError.at("--discovery-server", "must be IPV4[:PORT]", text,
                             "e.g. 127.0.0.1 or 192.168.1.10:11811") from None
    if not 1 <= port <= 65535:
        raise ConfigError.at("--discovery-server", "port out of range 1..65535", port)
    return host, port


def check_reach(env: dict[str, str], remote: list[int], server: bool = False) -> None:
    """Refuse remote robots that discovery limited to this host could never find (``env``: the
    launcher's environment; ``server``: a discovery server will be run)."""
    if not remote or server or env.get("ROS_DISCOVERY_SERVER"):
        return
    if env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST") in ("LOCALHOST", "OFF") and \
            not env.get("ROS_STATIC_PEERS"):
        raise ConfigError.at(
            "--remote-robots", "robots on other hosts need DDS discovery beyond this host, "
            f"but ROS_AUTOMATIC_DISCOVERY_RANGE is "
            f"{env.get('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST (the default here)')}",
            remote, "export ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET (or ROS_STATIC_PEERS=<the "
            "robots' hosts>), or --discovery-server <this host's address>")


#: DDS participants on one host beyond which simple discovery is not to be relied on
#: (scripts/bench_discovery: 16 all saw each other 1.2 s after the last came up; of 36, 4 had
#: not seen everyone 90 s later, the poorest 33 nodes; of 64 only 11 had; with the discovery
#: server all did, 36 in 4.1 s, 64 in 38 s).
SIMPLE_DISCOVERY_LIMIT = 32


def discovery_advice(participants: int, server: bool) -> str | None:
    """A warning for a run whose ``participants`` (robots, world, viewers, launcher) may not all
    find each other with simple discovery; None when all is well."""
    if server or participants <= SIMPLE_DISCOVERY_LIMIT:
        return None
    return (f"warning: {participants} DDS participants (processes) with simple discovery: on "
            f"one host beyond {SIMPLE_DISCOVERY_LIMIT} some may never find the others (36: four "
            "did not within 90 s, scripts/bench_discovery); --discovery-server or more robots "
            "per process (--robots-per-process) avoid that")


def discovery_server_executable() -> tuple[str, dict[str, str]]:
    """The ``fast-discovery-server`` of this environment and the ``LD_LIBRARY_PATH`` it needs
    (the ROS wheels keep their shared libraries in ``<venv>/lib`` and ``*.libs`` folders)."""
    exe = Path(sys.executable).with_name("fast-discovery-server")
    if not exe.is_file():
        found = shutil.which("fast-discovery-server")
        if found is None:
            raise ConfigError.at("--discovery-server", "fast-discovery-server not found (it "
                                 "ships with the ROS 2 wheels: scripts/bootstrap.sh)", "")
        exe = Path(found)
    site = Path(sysconfig.get_paths()["purelib"])
    folders = [str(Path(sys.prefix) / "lib")] + sorted(str(p) for p in site.glob("*.libs"))
    previous = os.environ.get("LD_LIBRARY_PATH")
    return str(exe), {"LD_LIBRARY_PATH": ":".join(folders + ([previous] if previous else []))}


def start_discovery_server(procs, address: tuple[str, int]) -> None:
    """Run the server as the launcher's child ``discovery``; return once it says it runs."""
    exe, lib_env = discovery_server_executable()
    host, port = address
    child = procs.start("discovery", [exe, "-i", "0", "-l", host, "-p", str(port)],
                        extra_env=lib_env)
    deadline = time.monotonic() + DISCOVERY_START_TIMEOUT
    while "Server is running" not in child.log.read_text(errors="replace"):
        if not child.alive or time.monotonic() > deadline:
            raise RuntimeError(f"the discovery server on {host}:{port} did not start:\n"
                               f"{procs.tail(child)}")
        time.sleep(0.05)


def _exports(env: dict[str, str]) -> list[str]:
    return [f"ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']}"] + [
        f"{k}={env[k]}" for k in FORWARDED_ENV if env.get(k)]


def remote_command(env: dict[str, str], cmd: list[str]) -> str:
    """What to run on a remote robot's host: the exports and the ``ros2 run`` line."""
    args = cmd[3:] if cmd[0] == sys.executable else cmd[1:]  # without "python -m module"
    return (f"{shlex.join(['export', *_exports(env)])}; "
            f"ros2 run coverage_ros robot_node {shlex.join(args)}")


def write_remote_script(path: Path, env: dict[str, str], cmd: list[str]) -> Path:
    """``path``: a shell script that runs the robot as the launcher would have, for a host with
    the same installation layout (this one's paths) - and the ``ros2 run`` line as a comment."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("#!/bin/sh\n"
                    f"# on a ROS 2 host: {remote_command(env, cmd)}\n"
                    f"{shlex.join(['export', *_exports(env)])}\n"
                    f"exec {shlex.join(cmd)}\n")
    path.chmod(0o755)
    return path
