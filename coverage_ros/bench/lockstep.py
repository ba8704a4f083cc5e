"""Lock-step reproducibility and speed (``scripts/bench_lockstep``).

Runs each scenario with ``coverage-team --lockstep`` twice with one seed - the second time
beside CPU hogs (busy processes, one per ``--hogs``) - and compares the two ``summary.json``
files without their wall-clock figures (:func:`~coverage_ros.cli.team.summary.deterministic_part`):
H series, final poses, path lengths, collisions, exploration series. Prints one line per
scenario (identical or the first differences, the real-time factor of each run) and, last, a
JSON line; ``--json PATH`` writes it too (with machine, date and commit).
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
from pathlib import Path

from coverage_ros.bench.environment import SANDBOX
from coverage_ros.bench.results import provenance
from coverage_ros.cli.team.summary import deterministic_part

TEAM = [sys.executable, "-m", "coverage_ros.cli.team"]
MIXED = """\
robots:
  - {id: 0, radius: 0.105, v_max: 0.22, sensor_radius: 1.2, power_weight: sensor}
  - {id: 1, radius: 0.105, v_max: 0.22, sensor_radius: 1.2, power_weight: sensor}
  - {id: 2, radius: 0.16, v_max: 0.15, sensor_radius: 0.6, power_weight: sensor}
  - {id: 3, radius: 0.16, v_max: 0.15, sensor_radius: 0.6, power_weight: sensor}
"""

#: name -> coverage-team arguments (4 robots on tb3_sandbox unless they say otherwise).
SCENARIOS: dict[str, list[str]] = {
    "geodesic": ["--strategy", "geodesic"],
    "lloyd, one process": ["--strategy", "lloyd", "--robots-per-process", "4"],
    "tangentbug": ["--strategy", "tangentbug"],
    "bvc, map-free": ["--strategy", "bvc", "--map-free"],
    "acvt": ["--strategy", "acvt"],
    "explore": ["--explore", "--world", "office", "--duration", "60"],
    "mixed team, 2 processes": ["--team", "{mixed}", "--robots-per-process", "2"],
    "region": ["--region", "-1.5,-1.5;0.5,-1.5;0.5,0.5;-1.5,0.5"],
}


def differences(a, b, path: str = "") -> list[str]:
    """Where two JSON values differ (paths), at most a few."""
    if type(a) is not type(b):
        return [f"{path}: {a!r} / {b!r}"]
    if isinstance(a, dict):
        return [d for k in sorted(set(a) | set(b)) for d in differences(a.get(k), b.get(k),
                                                                  f"{path}.{k}")][:5]
    if isinstance(a, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} / {len(b)} items"]
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True))
                for d in differences(x, y, f"{path}[{i}]")][:5]
    return [] if a == b else [f"{path}: {a!r} / {b!r}"]


@contextlib.contextmanager
def cpu_hogs(count: int):
    """``count`` busy processes (each its own process group) for the block's duration."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"],
                              start_new_session=True) for _ in range(count)]
    try:
        yield
    finally:
        for p in procs:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGKILL)
            p.wait()


def run_team(args: list[str], out: Path) -> dict:
    proc = subprocess.run(TEAM + ["--quiet", "--lockstep", "--out", str(out), *args],
                          capture_output=True, text=True, timeout=1800)
    if proc.returncode != 0:
        raise RuntimeError(f"coverage-team {' '.join(args)} failed:\n{proc.stderr[-2000:]}")
    return json.loads((out / "summary.json").read_text())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", action="append", choices=sorted(SCENARIOS),
                    help="run only these scenarios (repeatable)")
    ap.add_argument("--duration", type=float, default=60.0, help="[s] sim time per run")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--hogs", type=int, default=2, help="busy processes beside the second run")
    ap.add_argument("--json", type=Path, help="also write the results here")
    args = ap.parse_args(argv)
    rows: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="bench-lockstep-") as tmp:
        (Path(tmp) / "mixed.yaml").write_text(MIXED)
        for name in args.only or SCENARIOS:
            extra = [a.replace("{mixed}", str(Path(tmp) / "mixed.yaml"))
                     for a in SCENARIOS[name]]
            base = ["--world", str(SANDBOX), "--robots", "4", "--duration",
                    f"{args.duration:g}", "--seed", str(args.seed)]
            cmd = base + extra  # (later options win: a scenario may set world or duration)
            outs = [Path(tmp) / f"{len(rows)}-{k}" for k in (1, 2)]
            print(f"[bench_lockstep] {name}: coverage-team {' '.join(cmd)}", file=sys.stderr,
                  flush=True)
            first = run_team(cmd, outs[0])
            with cpu_hogs(args.hogs):
                second = run_team(cmd, outs[1])
            diff = differences(deterministic_part(first), deterministic_part(second))
            row = {"scenario": name, "identical": not diff, "differences": diff,
                   "rtf": first["rtf"], "rtf_beside_hogs": second["rtf"],
                   "H": first["metrics"]["H"], "H_start": first["metrics"]["H_start"],
                   "collisions": sum(r["collisions"] for r in first["robots"])}
            rows.append(row)
            print(f"[bench_lockstep] {name}: {'identical' if not diff else 'DIFFERENT'}"
                  f" (rtf {row['rtf']:.2f}, beside {args.hogs} hogs {row['rtf_beside_hogs']:.2f}"
                  f"; H {row['H']:.4g} from {row['H_start']:.4g}; collisions "
                  f"{row['collisions']})" + "".join(f"\n    {d}" for d in diff),
                  file=sys.stderr, flush=True)
    result = {**provenance(), "command": "scripts/bench_lockstep " + " ".join(
        sys.argv[1:] if argv is None else argv),
              "identical": sum(r["identical"] for r in rows), "scenarios": len(rows),
              "rows": rows}
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=2))
    print(json.dumps(result))
    return 0 if result["identical"] == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
