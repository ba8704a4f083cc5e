"""``scripts/bench_papers``: run the papers' experiments over their seeds and print the table.

    scripts/bench_papers [--paper lee,wang,breitenmoser,bhattacharya] [--only TEXT]
                         [--quick] [--no-live] [--seeds N] [--jobs N]
                         [--markdown FILE] [--json FILE]

Offline runs of different seeds and experiments go to ``--jobs`` worker processes; live-team
experiments (processes over DDS, timed in sim time) run one at a time after them, alone on the
machine. Progress goes to stderr; stdout gets the Markdown table and, as its last line, JSON:
``{"rows": [{"paper", "figure", "metric", "paper_value", "ours_median", "ours_worst", "seeds",
"verdict", ...}, ...]}``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import traceback
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from coverage_ros.bench.papers import PAPERS, Experiment, experiments_by_paper
from coverage_ros.bench.papers.table import markdown, rows_of
from coverage_ros.errors import ConfigError


def _say(text: str) -> None:
    print(f"[bench_papers] {text}", file=sys.stderr, flush=True)


def run_one(paper: str, key: str, seed: int) -> tuple[dict[str, float] | None, float, str]:
    """Run experiment ``key`` of ``paper`` (a short name) for ``seed`` (in a worker process):
    ``(values or None, wall seconds, error text)``."""
    exp = next(e for _, e in experiments_by_paper([paper]) if e.key == key)
    t0 = time.perf_counter()
    try:
        values = {k: float(v) for k, v in exp.run(seed).items()}
        return values, time.perf_counter() - t0, ""
    except Exception:  # a failed run is a row's missing value, never the end of the table
        return None, time.perf_counter() - t0, traceback.format_exc(limit=6)


def select(args: argparse.Namespace) -> list[tuple[str, Experiment]]:
    """``(short paper name, experiment)`` pairs chosen by the command line."""
    papers = None if args.paper is None else [p.strip() for p in args.paper.split(",")
                                              if p.strip()]
    chosen = experiments_by_paper(papers)
    if args.only:
        chosen = [(p, e) for p, e in chosen if args.only.lower() in e.key.lower()]
    if args.quick:
        chosen = [(p, e) for p, e in chosen if not (e.slow or e.live)]
    if args.no_live:
        chosen = [(p, e) for p, e in chosen if not e.live]
    if not chosen:
        raise ConfigError.at("--only/--quick/--paper", "select no experiment")
    return chosen


def _progress(exp: Experiment, seed: int, n: int, values: Mapping[str, float] | None,
              wall: float, error: str) -> None:
    if values is None:
        _say(f"{exp.key} seed {seed + 1}/{n}: FAILED after {wall:.1f} s\n{error}")
        return
    shown = ", ".join(f"{k} {v:.4g}" for k, v in values.items())
    _say(f"{exp.key} seed {seed + 1}/{n}: {shown} ({wall:.1f} s)")


def run_all(chosen: list[tuple[str, Experiment]], seeds: int | None, jobs: int) -> list:
    """Every chosen experiment over its seeds; returns the rows in table order."""
    plan = {e.key: (e, seeds or e.seeds) for _, e in chosen}
    paper_of = {e.key: p for p, e in chosen}
    results: dict[str, list] = {k: [None] * n for k, (_, n) in plan.items()}
    offline = [(k, s) for k, (e, n) in plan.items() if not e.live for s in range(n)]
    live = [(k, s) for k, (e, n) in plan.items() if e.live for s in range(n)]
    total = len(offline) + len(live)
    _say(f"{len(chosen)} experiments, {total} runs ({len(live)} on the live team), "
         f"{jobs} jobs")
    done = 0
    if offline:
        with ProcessPoolExecutor(max_workers=max(1, jobs)) as pool:
            futures = {pool.submit(run_one, paper_of[k], k, s): (k, s) for k, s in offline}
            for fut in as_completed(futures):
                k, s = futures[fut]
                values, wall, error = fut.result()
                results[k][s] = values
                done += 1
                _progress(plan[k][0], s, plan[k][1], values, wall, error)
                _say(f"{done}/{total} runs done")
    for k, s in live:  # alone: the live team is timed in sim time against the wall clock
        values, wall, error = run_one(paper_of[k], k, s)
        results[k][s] = values
        done += 1
        _progress(plan[k][0], s, plan[k][1], values, wall, error)
        _say(f"{done}/{total} runs done")
    rows = []
    for k, (e, _) in plan.items():
        rows.extend(rows_of(e, results[k]))
    return rows


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="bench_papers", description=__doc__.split("\n\n")[0])
    ap.add_argument("--paper", default=None,
                    help=f"comma-separated papers to run ({', '.join(PAPERS)}); default all")
    ap.add_argument("--only", default="", help="only experiments whose key contains this text")
    ap.add_argument("--quick", action="store_true",
                    help="leave out slow (minutes per seed) and live-team experiments")
    ap.add_argument("--no-live", action="store_true", help="leave out live-team experiments")
    ap.add_argument("--seeds", type=int, default=None,
                    help="seeds per experiment (default: each experiment's own, at least 5)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="worker processes for offline runs (default: the cores)")
    ap.add_argument("--markdown", type=Path, default=None, help="also write the table here")
    ap.add_argument("--json", type=Path, default=None, help="also write the JSON here")
    ap.add_argument("--list", action="store_true", help="list the experiments and stop")
    ap.add_argument("--no-results", action="store_true",
                    help="do not update docs/results/papers.json (each row replaces the same "
                    "paper, figure, setting and metric's row there)")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.seeds is not None and args.seeds < 1:
            raise ConfigError.at("--seeds", "must be >= 1", args.seeds)
        chosen = select(args)
    except ConfigError as exc:
        print(f"bench_papers: error: {exc}", file=sys.stderr)
        return 2
    if args.list:
        for _, e in chosen:
            flags = ", ".join(f for f, on in (("slow", e.slow), ("live", e.live),
                                              ("re-drawn", e.redrawn)) if on)
            print(f"{e.key} ({e.paper}, {e.figure}): {e.setting} "
                  f"[{e.seeds} seeds{', ' + flags if flags else ''}]")
        return 0
    t0 = time.perf_counter()
    rows = run_all(chosen, args.seeds, args.jobs)
    table = markdown(rows)
    json_rows = [r.as_json() for r in rows]
    payload = {"rows": json_rows, "wall_time_s": time.perf_counter() - t0}
    if args.markdown:
        args.markdown.write_text(table + "\n")
    if args.json:
        args.json.write_text(json.dumps(payload, indent=1) + "\n")
    if not args.no_results:
        from coverage_ros.bench.results import update_rows

        update_rows("papers", json_rows, ("paper", "figure", "setting", "metric"), argv,
                    "scripts/bench_papers")
    print(table)
    ours = [r for r in rows if not r.baseline]
    counts = {v: sum(r.verdict == v for r in ours) for v in
              ("as good or better", "within 20 %", "worse")}
    _say(f"{len(rows)} rows in {payload['wall_time_s']:.0f} s; of the {len(ours)} rows of the "
         "papers' own methods: " + ", ".join(f"{n} {v}" for v, n in counts.items()))
    print(json.dumps(payload))
    return 0


if __name__ == "__main__":
    sys.exit(main())
