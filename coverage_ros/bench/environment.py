"""What the benchmark harnesses share: where the repository, the shared maps and the launcher
are, and network namespaces for runs on lossy links or several hosts (``ip netns``, nftables)."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import uuid
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SHARED_MAPS = REPO.parent / "shared" / "maps"
DEPOT = SHARED_MAPS / "depot.yaml"
SANDBOX = SHARED_MAPS / "tb3_sandbox.yaml"
def have_tools() -> str:
    """'' when ip and nft are there (and we may use them), else what is missing."""
    missing = [t for t in ("ip", "nft") if shutil.which(t) is None]
    if missing:
        return f"missing {', '.join(missing)} (nftables and iproute2 are Debian packages)"
    if os.geteuid() != 0:
        return "network namespaces need root"
    return ""


@contextlib.contextmanager
def lossy_namespace(loss_percent: float) -> Iterator[str]:
    """A fresh network namespace (loopback up) silently dropping ``loss_percent`` % of the UDP
    packets; yields its name, deletes it afterwards (its processes must have ended)."""
    if not 0 <= loss_percent <= 100:
        raise ValueError(f"loss_percent must be in 0..100, got {loss_percent}")
    name = f"cov-loss-{uuid.uuid4().hex[:8]}"
    subprocess.run(["ip", "netns", "add", name], check=True)
    try:
        subprocess.run(["ip", "-n", name, "link", "set", "lo", "up"], check=True)
        if loss_percent > 0:
            rules = ("table inet coverage_loss {\n"
                     "  chain in {\n"
                     "    type filter hook input priority 0; policy accept;\n"
                     f"    meta l4proto udp numgen random mod 100 < {int(round(loss_percent))}"
                     " drop\n"
                     "  }\n"
                     "}\n")
            subprocess.run(["ip", "netns", "exec", name, "nft", "-f", "-"], input=rules,
                           text=True, check=True)
        yield name
    finally:
        subprocess.run(["ip", "netns", "del", name], check=False)


def namespace_env(extra: dict[str, str] | None = None) -> dict[str, str]:
    """The environment of a team in a lossy namespace: UDP only, this host only."""
    env = dict(os.environ)
    env["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env.update(extra or {})
    return env


def run_team_in(namespace: str, out: Path, team_args: list[str], timeout: float = 900,
                quiet: bool = True) -> dict:
    """``coverage-team`` inside ``namespace``; its summary.json (RuntimeError if it failed)."""
    exe = str(REPO / ".venv" / "bin" / "coverage-team")
    cmd = ["ip", "netns", "exec", namespace, exe, *(["--quiet"] if quiet else []),
           "--out", str(out), *team_args]
    proc = subprocess.run(cmd, env=namespace_env(), capture_output=True, text=True,
                          timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"coverage-team in {namespace} failed ({proc.returncode}):\n"
                           f"{proc.stderr[-3000:]}")
    return json.loads((out / "summary.json").read_text())
