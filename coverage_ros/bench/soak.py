"""A long run with faults (``scripts/bench_faults --only soak``): 8 robots for 30 minutes of sim
time at the fastest real-time factor at which the team still keeps up on this machine (2: at
``--rtf 0`` the world ran 25 x real time and the robots' updates fell so far behind in sim time
that they collided), one robot's process killed
and started again every ``period`` seconds of sim time (``--restart``), while this harness
samples the memory (RSS) of every process of the team.

Figures: ``rss_growth``, the largest relative growth of any process's RSS after its warm-up
(the median RSS over the last tenth of its life against the median over the tenth after
warm-up; warm-up is the first ``WARMUP`` of its life, or longer, until its RSS first reaches
``SETTLED`` of its median over the life: a start-up that outlasts the share is not a leak, while
a steady leak reaches that level by 45 % of the life and still shows); ``log_bytes`` (all
logs) and the log bytes of the second half of the run against the first (bounded logs grow
linearly at most); and ``recovered``: after each restart, whether H came back within 10 % of
its value before the fault within ``RECOVERY`` seconds of sim time.
"""

from __future__ import annotations

import contextlib
import json
import subprocess
import time
from pathlib import Path

import numpy as np

from coverage_ros.bench.environment import REPO

WARMUP = 0.25  # share of a process's life before its RSS counts
SETTLED = 0.9  # share of the life's median RSS that ends a start-up
#: [samples] a shorter life is no measure of growth: on a slow host a robot's imports alone take
#: 15 s (its RSS climbs from 16 to 150 MB), past the warm-up share of a half-minute life
MIN_SAMPLES = 30
RECOVERY = 120.0  # [s] sim time for H to come back after a restart
SAMPLE_PERIOD = 5.0  # [s] wall


def _process_name(cmdline: list[str], comm: str = "") -> str | None:
    if comm.startswith(("robot_", "robots_")):  # forked by the launcher's fork server: its name
        return comm
    text = " ".join(cmdline)
    for key in ("robot_node", "world_node", "rerun_bridge", "marker_node", "coverage-team"):
        if key in text:
            if key == "robot_node":
                for part in cmdline:
                    if part.startswith("robot_id:="):
                        return f"robot_{part.split(':=')[1]}"
            return key
    return None


def growth(samples: list[tuple[float, float]]) -> float | None:
    """Relative RSS growth of one process from ``[(wall, rss), ...]`` (None: too short)."""
    if len(samples) < MIN_SAMPLES:
        return None
    rss = np.array([r for _, r in samples])
    n = len(rss)
    settled = int(np.argmax(rss >= SETTLED * np.median(rss)))
    start = min(max(int(WARMUP * n), settled), n - 2 * max(n // 10, 2))
    tenth = max(n // 10, 2)
    base = float(np.median(rss[start:start + tenth]))
    last = float(np.median(rss[-tenth:]))
    return last / base - 1.0


def soak_section(duration: float, folder: Path, say, robots: int = 8, world: str = "office",
                 period: float = 180.0, rtf: float = 2.0,
                 sample_period: float = SAMPLE_PERIOD, domain: int | None = None,
                 strategy_params: str | None = None) -> dict:
    """``domain``: the team's ROS_DOMAIN_ID (None: a fresh one the launcher picks);
    ``strategy_params``: the launcher's ``--strategy-params`` (None: the defaults)."""
    import psutil

    out = folder / "soak"
    restarts = [f"{k % robots}@{t:g}" for k, t in enumerate(np.arange(period, duration, period))]
    cmd = [str(REPO / ".venv" / "bin" / "coverage-team"), "--quiet", "--robots", str(robots),
           "--world", world, "--duration", f"{duration:g}", "--rtf", f"{rtf:g}", "--record",
           "--out", str(out)] + [a for r in restarts for a in ("--restart", r)]
    if domain is not None:
        cmd += ["--domain-id", str(domain)]
    if strategy_params is not None:
        cmd += ["--strategy-params", strategy_params]
    say(f"soak: {robots} robots on {world} for {duration:g} s sim time at {rtf:g} x real time, "
        f"{len(restarts)} restarts ...")
    launcher = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True, start_new_session=True)
    assert launcher.stderr is not None
    samples: dict[tuple[int, str], list[tuple[float, float]]] = {}
    logs_half: list[tuple[float, int]] = []
    t0 = last_say = time.monotonic()
    parent = psutil.Process(launcher.pid)
    while launcher.poll() is None:
        now = time.monotonic()
        with contextlib.suppress(psutil.Error):
            for proc in [parent, *parent.children(recursive=True)]:
                with contextlib.suppress(psutil.Error):
                    name = _process_name(proc.cmdline(), proc.name())
                    if name is not None:
                        samples.setdefault((proc.pid, name), []).append(
                            (now - t0, proc.memory_info().rss / 2**20))
        logs_half.append((now - t0, _folder_bytes(out / "logs")))
        if now - last_say > 60:
            last_say = now
            say(f"  {now - t0:.0f} s wall, {len(samples)} processes seen, logs "
                f"{logs_half[-1][1] / 1024:.0f} kB")
        time.sleep(sample_period)
    err = launcher.stderr.read()
    if launcher.returncode != 0:
        raise RuntimeError(f"soak run failed ({launcher.returncode}):\n{err[-3000:]}")
    summary = json.loads((out / "summary.json").read_text())
    per_process = {f"{name}[{pid}]": g for (pid, name), s in samples.items()
                   if (g := growth(s)) is not None}
    worst = max(per_process, key=lambda k: per_process[k]) if per_process else None
    worst_series = next((s for (pid, name), s in samples.items()
                         if f"{name}[{pid}]" == worst), [])
    stride = max(len(worst_series) // 30, 1)
    wall = time.monotonic() - t0
    first = next((b for t, b in logs_half if t >= wall / 2), logs_half[-1][1])
    total = _folder_bytes(out / "logs")
    series = summary["metrics"]["H_series"]
    recovered = _recoveries(series, restarts)
    return {"sim_time": summary["sim_time"], "wall_time": round(wall, 1), "rtf": summary["rtf"],
            "rtf_asked": rtf,
            "robots": robots, "restarts": restarts,
            "rss_growth": round(per_process[worst], 4) if worst else None,
            "rss_growth_worst_process": worst,
            "rss_mb_worst_series": [[round(t), round(r, 1)] for t, r in worst_series[::stride]],
            "rss_growth_per_process": {k: round(v, 4) for k, v in sorted(per_process.items())},
            "rss_mb_last": {name: round(s[-1][1], 1) for (_, name), s in samples.items()},
            "log_bytes": total, "log_bytes_first_half": first,
            "log_bytes_second_half": total - first,
            "recovered": recovered, "H_final": summary["metrics"]["H"],
            "H_start": summary["metrics"]["H_start"],
            "collisions": sum(r["collisions"] for r in summary["robots"]),
            "collisions_by_robot": {r["id"]: {"robots": r.get("robot_collisions", 0),
                                              "walls": r.get("wall_collisions", 0)}
                                    for r in summary["robots"] if r["collisions"]}}


def _recoveries(series: list[list[float]], restarts: list[str]) -> list[dict]:
    """For each restart at sim time t: H just before it and the best H within RECOVERY."""
    out = []
    for item in restarts:
        rid, at = item.split("@")
        t = float(at)
        before = [h for s, h in series if s <= t]
        after = [h for s, h in series if t < s <= t + RECOVERY]
        if not before or not after:
            continue
        ok = min(after) <= 1.10 * before[-1]
        out.append({"robot": int(rid), "at": t, "H_before": round(before[-1], 3),
                    "H_best_after": round(min(after), 3), "recovered": ok})
    return out


def _folder_bytes(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.glob("*") if p.is_file()) if folder.exists() \
        else 0
