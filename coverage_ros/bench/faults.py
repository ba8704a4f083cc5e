"""Faults on the live team (``scripts/bench_faults``): lossy links.

A team runs in a network namespace of its own (``ip netns``), where nftables drops a random
share of the UDP packets arriving at any socket (``numgen random mod 100 < P drop`` on the input
hook: each packet is dropped once, with probability P, silently - a drop on the output hook
would fail the sender's ``sendto`` with EPERM instead, which a radio never does; loopback is the
only interface, so DDS cannot reach anything outside). Fast DDS would carry same-host traffic
over shared memory, which no packet filter sees, so the namespace's processes use UDP only
(``FASTDDS_BUILTIN_TRANSPORTS=UDPv4``). This machine's kernel has no netem; nftables is a Debian
package (``scripts/bootstrap.sh`` installs it when missing).

For each loss level the same team (world, robots, seed, duration) runs once, and the figures are
its H over the H of the lossless run in the same namespace set-up (``H_ratio``), collisions and
the time to convergence. Progress goes to stderr; the last stdout line is JSON:
``{"loss": {"0.1": {"H_ratio", "collisions", "converged_at", "H"}, ...}, "lossless": {...}}``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import uuid
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SHARED_MAPS = REPO.parent / "shared" / "maps"
#: Issue target: at 20 % loss H within 15 % of the lossless run.
TARGET_RATIO = 1.15


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


def figures(summary: dict, reference_H: float | None) -> dict:
    m = summary["metrics"]
    return {"H": m["H"], "H_start": m["H_start"],
            "H_ratio": None if not reference_H else round(m["H"] / reference_H, 4),
            "collisions": sum(r["collisions"] for r in summary["robots"]),
            "converged_at": m["converged_at"], "rtf": summary["rtf"]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--world", default=str(SHARED_MAPS / "tb3_sandbox.yaml"))
    ap.add_argument("--robots", type=int, default=4)
    ap.add_argument("--duration", type=float, default=90.0)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--loss", type=float, nargs="+", default=[0.1, 0.2, 0.4],
                    help="shares of UDP packets dropped")
    args = ap.parse_args(argv)
    problem = have_tools()
    if problem:
        print(f"bench_faults: error: {problem}", file=sys.stderr)
        return 2
    team_args = ["--world", args.world, "--robots", str(args.robots), "--duration",
                 str(args.duration), "--seed", str(args.seed), "--no-markers"]
    results: dict = {"loss": {}}
    with tempfile.TemporaryDirectory(prefix="bench_faults-") as tmp:
        print(f"lossless reference: {args.robots} robots, {args.duration:g} s on "
              f"{Path(args.world).name}", file=sys.stderr, flush=True)
        with lossy_namespace(0) as ns:
            ref = run_team_in(ns, Path(tmp) / "lossless", team_args)
        ref_H = ref["metrics"]["H"]
        results["lossless"] = figures(ref, ref_H)
        print(f"  H {ref_H:.3f}", file=sys.stderr, flush=True)
        for share in args.loss:
            print(f"{100 * share:.0f} % of UDP packets dropped ...", file=sys.stderr, flush=True)
            with lossy_namespace(100 * share) as ns:
                s = run_team_in(ns, Path(tmp) / f"loss-{share}", team_args)
            f = figures(s, ref_H)
            results["loss"][f"{share:g}"] = f
            print(f"  H {f['H']:.3f} ({f['H_ratio']:.3f} x lossless), collisions "
                  f"{f['collisions']}, converged at {f['converged_at']} s, rtf {f['rtf']}",
                  file=sys.stderr, flush=True)
    lines = ["| loss | H | H / lossless | collisions | converged at [s] |",
             "|---|---|---|---|---|",
             f"| 0 | {ref_H:.3f} | 1.000 | {results['lossless']['collisions']} | "
             f"{results['lossless']['converged_at']} |"]
    for share, f in results["loss"].items():
        lines.append(f"| {float(share):.0%} | {f['H']:.3f} | {f['H_ratio']:.3f} | "
                     f"{f['collisions']} | {f['converged_at']} |")
    print("\n".join(lines), file=sys.stderr)
    at20 = results["loss"].get("0.2")
    if at20 is not None:
        met = at20["H_ratio"] <= TARGET_RATIO and at20["collisions"] == 0
        print(f"target (20 % loss: H within {TARGET_RATIO - 1:.0%} of lossless, no "
              f"collisions): {'met' if met else 'NOT met'}", file=sys.stderr)
    print(json.dumps(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
