"""Faults on the live team (``scripts/bench_faults``): lossy links, several hosts, restarts,
malformed messages on every subscribed topic (``bench/fuzz.py``) and a long soak
(``bench/soak.py``).

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
the time to convergence; the three-host runs (``bench/hosts.py``) and the restarts are scored
against the same reference. Progress goes to stderr; the last stdout line is JSON:
``{"loss": {"0.1": {"H_ratio", "collisions", "converged_at", "H"}, ...}, "hosts": {"H_ratio",
"collisions", ..., "discovery_server": {...}}, "restarts": {...}, "fuzz": {"messages",
"node_crashes", ...}, "soak": {"rss_growth", "log_bytes", ...}, "lossless": {...}}``; each
fault's row replaces that fault's row in ``docs/results/faults.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from coverage_ros.bench.environment import (
    SANDBOX,
    have_tools,
    lossy_namespace,
    run_team_in,
)
from coverage_ros.bench.fuzz import fuzz_section
from coverage_ros.bench.hosts import hosts_network, run_across_hosts
from coverage_ros.bench.soak import soak_section

#: Target: at 20 % loss H within 15 % of the lossless run.
TARGET_RATIO = 1.15


def figures(summary: dict, reference_H: float | None) -> dict:
    m = summary["metrics"]
    return {"H": m["H"], "H_start": m["H_start"],
            "H_ratio": None if not reference_H else round(m["H"] / reference_H, 4),
            "collisions": sum(r["collisions"] for r in summary["robots"]),
            "converged_at": m["converged_at"], "rtf": summary["rtf"]}


SECTIONS = ("loss", "hosts", "restarts", "fuzz", "soak")


def loss_section(args, team_args: list[str], tmp: Path, ref_H: float | None, say) -> dict:
    out = {}
    for share in args.loss:
        say(f"{100 * share:.0f} % of UDP packets dropped ...")
        with lossy_namespace(100 * share) as ns:
            s = run_team_in(ns, tmp / f"loss-{share}", team_args)
        f = out[f"{share:g}"] = figures(s, ref_H)
        say(f"  H {f['H']:.3f} ({f['H_ratio']:.3f} x lossless), collisions {f['collisions']}, "
            f"converged at {f['converged_at']} s, rtf {f['rtf']}")
    return out


def hosts_section(args, team_args: list[str], tmp: Path, ref_H: float | None, say) -> dict:
    """Three hosts: world and robots 0-1 on the first, robot 2 on the second, robot 3 (and any
    further ones, alternately) on the third; simple discovery, then a discovery server."""

    remote = {rid: 1 + (rid % 2) for rid in range(2, args.robots)}
    out: dict = {}
    for server in (False, True):
        say(f"3 hosts, robots {sorted(remote)} remote, "
            f"{'discovery server' if server else 'simple discovery'} ...")
        with hosts_network(3, multicast=not server) as hosts:
            run = run_across_hosts(hosts, tmp / f"hosts-{server}", team_args, remote, server)
        f = figures(run.summary, ref_H)
        f["link_packets"] = sorted(run.packets.values())
        say(f"  H {f['H']:.3f} ({f['H_ratio']:.3f} x one host), collisions {f['collisions']}")
        if server:
            out["discovery_server"] = f
        else:
            out.update(f)
    return out


def restarts_section(args, team_args: list[str], tmp: Path, ref_H: float | None, say) -> dict:
    """Robot 1's process killed and started again a third into the run, robot 2's at half."""
    plan = [f"1@{args.duration / 3:g}", f"2@{args.duration / 2:g}"]
    say(f"restarts {', '.join(plan)} ...")
    with lossy_namespace(0) as ns:
        s = run_team_in(ns, tmp / "restarts", team_args + [
            a for p in plan for a in ("--restart", p)])
    f = figures(s, ref_H)
    f["restarted"] = plan
    say(f"  H {f['H']:.3f} ({f['H_ratio']:.3f} x without), collisions {f['collisions']}")
    return f


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--world", default=str(SANDBOX))
    ap.add_argument("--robots", type=int, default=4)
    ap.add_argument("--duration", type=float, default=90.0)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--loss", type=float, nargs="+", default=[0.1, 0.2, 0.4],
                    help="shares of UDP packets dropped")
    ap.add_argument("--only", nargs="+", choices=SECTIONS, default=list(SECTIONS),
                    help="run only these parts")
    ap.add_argument("--soak-duration", type=float, default=1800.0,
                    help="[s] sim time of the soak run")
    ap.add_argument("--fuzz-examples", type=int, default=60,
                    help="hypothesis examples per subscribed topic")
    ap.add_argument("--no-results", action="store_true",
                    help="do not update docs/results/faults.json")
    args = ap.parse_args(argv)
    problem = have_tools()
    if problem:
        print(f"bench_faults: error: {problem}", file=sys.stderr)
        return 2

    def say(text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    team_args = ["--world", args.world, "--robots", str(args.robots), "--duration",
                 str(args.duration), "--seed", str(args.seed), "--no-markers"]
    results: dict = {}
    with tempfile.TemporaryDirectory(prefix="bench_faults-") as tmp_name:
        tmp = Path(tmp_name)
        ref_H = None
        if {"loss", "hosts", "restarts"} & set(args.only):
            say(f"reference: {args.robots} robots, {args.duration:g} s on "
                f"{Path(args.world).name}, one host, no faults")
            with lossy_namespace(0) as ns:
                ref = run_team_in(ns, tmp / "lossless", team_args)
            ref_H = ref["metrics"]["H"]
            results["lossless"] = figures(ref, ref_H)
            say(f"  H {ref_H:.3f}")
        if "loss" in args.only:
            results["loss"] = loss_section(args, team_args, tmp, ref_H, say)
        if "hosts" in args.only:
            results["hosts"] = hosts_section(args, team_args, tmp, ref_H, say)
        if "restarts" in args.only:
            results["restarts"] = restarts_section(args, team_args, tmp, ref_H, say)
        if "fuzz" in args.only:

            results["fuzz"] = fuzz_section(args.fuzz_examples, tmp, say)
        if "soak" in args.only:

            results["soak"] = soak_section(args.soak_duration, tmp, say)
    report(results, say)
    if not args.no_results:
        from coverage_ros.bench.results import update_rows

        settings = (f"{args.robots} robots on {Path(args.world).name}, {args.duration:g} s of "
                    f"sim time at real time, seed {args.seed}, one run per fault; parts run: "
                    f"{', '.join(args.only)}" + (f"; soak {args.soak_duration:g} s"
                                                 if "soak" in args.only else "")
                    + (f"; {args.fuzz_examples} malformed messages per topic"
                       if "fuzz" in args.only else ""))
        update_rows("faults", result_rows(results), ("fault",), argv, "scripts/bench_faults",
                    extra={"settings": settings})
    print(json.dumps(results))
    return 0


def result_rows(results: dict) -> list[dict]:
    """One row per fault for ``docs/results/faults.json``, with its target where it has one."""
    rows = []

    def team(name: str, f: dict | None, target: str = "", met: bool | None = None) -> None:
        if f:
            rows.append({"fault": name, "H": round(f["H"], 3), "H_ratio": f["H_ratio"],
                         "collisions": f["collisions"], "converged_at": f["converged_at"],
                         "target": target, "met": met})

    team("none (the reference)", results.get("lossless"))
    for level, f in results.get("loss", {}).items():
        at20 = float(level) == 0.2
        team(f"{float(level):.0%} of UDP packets dropped", f,
             f"H ratio <= {TARGET_RATIO}, no collision" if at20 else "",
             f["H_ratio"] <= TARGET_RATIO and f["collisions"] == 0 if at20 else None)
    if "hosts" in results:
        team("3 hosts, simple discovery", results["hosts"])
        team("3 hosts, discovery server", results["hosts"].get("discovery_server"))
    team("robots restarted", results.get("restarts"))
    fuzz = results.get("fuzz")
    if fuzz:
        rows.append({"fault": f"malformed messages on every subscribed topic ({fuzz['messages']}"
                     f" messages, {fuzz['topics']} topics)", "node_crashes": fuzz["node_crashes"],
                     "problems": len(fuzz["problems"]), "target": "no node crash, no problem",
                     "met": fuzz["node_crashes"] == 0 and not fuzz["problems"]})
    soak = results.get("soak")
    if soak:
        growth = soak["rss_growth"]
        rows.append({"fault": f"soak: {soak['robots']} robots, {soak['sim_time']:.0f} s, "
                     f"{len(soak['restarts'])} restarts", "rss_growth": growth,
                     "target": "memory growth < 5 %", "met": growth is not None and growth < 0.05})
    return rows


def report(results: dict, say) -> None:
    """The Markdown table of the runs and the targets, on stderr."""
    rows = [("no fault", results.get("lossless"))]
    rows += [(f"{float(k):.0%} UDP loss", v) for k, v in results.get("loss", {}).items()]
    if "hosts" in results:
        rows += [("3 hosts, simple discovery", results["hosts"]),
                 ("3 hosts, discovery server", results["hosts"]["discovery_server"])]
    rows.append(("2 robot restarts", results.get("restarts")))
    lines = ["| run | H | H / no fault | collisions | converged at [s] |", "|---|---|---|---|---|"]
    lines += [f"| {name} | {f['H']:.3f} | {f['H_ratio']:.3f} | {f['collisions']} | "
              f"{f['converged_at']} |" for name, f in rows if f]
    say("\n".join(lines))
    at20 = results.get("loss", {}).get("0.2")
    if at20 is not None:
        met = at20["H_ratio"] <= TARGET_RATIO and at20["collisions"] == 0
        say(f"target (20 % loss: H within {TARGET_RATIO - 1:.0%} of lossless, no collisions): "
            f"{'met' if met else 'NOT met'}")
    if "fuzz" in results:
        f = results["fuzz"]
        say(f"fuzz: {f['messages']} malformed messages on {f['topics']} topics, node crashes "
            f"{f['node_crashes']}")
    if "soak" in results:
        f = results["soak"]
        say(f"soak: {f['sim_time']:g} s sim, rss growth {f['rss_growth']:.1%} (target < 5 %: "
            f"{'met' if f['rss_growth'] < 0.05 else 'NOT met'}), logs {f['log_bytes']} bytes")


if __name__ == "__main__":
    sys.exit(main())
