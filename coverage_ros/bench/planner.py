"""``coverage-plan --strategy lloyd --solver lloyd`` end to end against CoverageControl's
clairvoyant Lloyd on the same scenario (``scripts/bench_planner``).

Scenario (CoverageControl's kind, world ``gaussians``): a 20 m square at 5 cm, a density of three
Gaussians, eight robots starting in a corner, plain Lloyd until no robot moves more than 0.1 mm
(CoverageControl's own stop: a robot within 1e-4 m of its last positions). CoverageControl
(KumarRobotics, the ``coverage-control`` wheel, C++) gets the same density grid (the free cells'
density, zero on the cells the robot radius keeps free of) and the same starts; it runs in its own
venv under the cache folder (made on first use: ``pip install coverage-control``), by
:mod:`coverage_ros.bench.coveragecontrol_lloyd`.

The same comparison then runs on random scenarios of that kind
(:mod:`coverage_ros.bench.cc_scenarios`, ``--e2e-scenarios``), each with its process's fixed
cost and the steps a run needs to pay it back.

Timed in rounds, each round one run of every kind back to back, so a change in the machine's
load hits all alike; the ratios are medians over rounds of the round's own ratio:

* ``end_to_end_ms_per_step`` - ours: wall time from starting the ``coverage-plan`` process to its
  exit (JSON written), divided by its steps (``cpu_ms_per_step``: the process's CPU time);
* ``step_ms`` - ours: the team step as ``coverage-plan`` reports it (solver time / steps);
* CoverageControl: ``step_ms`` (``ComputeActions`` + ``StepActions``, median),
  ``controller_step_ms`` (the same with the objective every step, as its ``ControllerCVT.step``),
  ``end_to_end_ms_per_step`` (its process, start to exit, divided by its steps) and
  ``cpu_ms_per_step`` (that process's CPU time: less at the mercy of the machine's load).
"""

from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from coverage_ros.bench import cc_scenarios
from coverage_ros.bench.environment import REPO
from coverage_ros.core.offline.lloyd_solvers import SETTLED
from coverage_ros.errors import ConfigError

WORLD = "gaussians"
ROBOTS = 8
TOLERANCE = 1e-4  # [m]
CC_VERSION = "1.3.1"
#: What an earlier measurement gave, used where CoverageControl cannot be installed.
CC_RECORDED: dict[str, Any] = {
    "step_ms": [1.6, 2.0], "steps": 339,
    "source": "CoverageControl 1.3.1 ClairvoyantCVT on this scenario, measured earlier on "
              "another machine (not re-measured here)"}


def cache_dir() -> Path:
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "coverage_ros"


def coveragecontrol_python(say) -> tuple[str | None, str]:
    """The interpreter of a venv with ``coverage-control`` (made once under :func:`cache_dir`),
    or None and why not."""
    venv = cache_dir() / f"coverage-control-{CC_VERSION}"
    py = venv / "bin" / "python"
    probe = [str(py), "-c", "import importlib.metadata as m; print(m.version('coverage_control'))"]
    if py.exists() and _output(probe) == CC_VERSION:
        return str(py), ""
    say(f"  making {venv} (pip install coverage-control=={CC_VERSION})")
    made = subprocess.run([sys.executable, "-m", "venv", "--clear", str(venv)],
                          capture_output=True, text=True)
    if made.returncode != 0:
        return None, f"venv: {made.stderr.strip()[-300:]}"
    pip = subprocess.run([str(py), "-m", "pip", "install", "-q",
                          f"coverage-control=={CC_VERSION}"],
                         capture_output=True, text=True, timeout=1200)
    if pip.returncode != 0 or _output(probe) != CC_VERSION:
        return None, f"pip install coverage-control=={CC_VERSION}: {pip.stderr.strip()[-300:]}"
    return str(py), ""


def _output(cmd: list[str]) -> str:
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=60).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def _timed(cmd: list[str], stdin: str = "") -> tuple[subprocess.CompletedProcess, float, float]:
    """Run ``cmd``; its wall time and CPU time [s] (the only child running meanwhile)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, input=stdin, capture_output=True, text=True, timeout=600)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if out.returncode != 0:
        raise RuntimeError(f"{cmd[0]} failed: {out.stderr[-2000:]}")
    return out, wall, cpu


def scenario(tmp: Path, world_name: str = WORLD, robots: int = ROBOTS) -> dict:
    """The scenario's density grid for CoverageControl (an ``.npy``: the world's bounds, rows
    along y), its first ``robots`` starts in that grid's frame and our domain's resolution."""
    from coverage_ros.core.geodesic.world_domain import world_domain
    from coverage_ros.core.world import load_world
    from coverage_ros.worlds import resolve_world_path

    world = load_world(resolve_world_path(world_name))
    domain = world_domain(world, world.robot_spec(0).radius)
    res = domain.resolution
    assert world.bounds is not None  # (the scenario's world is walled)
    x0, y0, x1, y1 = world.bounds
    ox, oy, _ = domain.geometry.origin
    c0, r0 = round((x0 - ox) / res), round((y0 - oy) / res)
    n = round((x1 - x0) / res)
    if round((y1 - y0) / res) != n:
        raise ValueError("CoverageControl's maps are square")
    density = np.where(domain.free, domain.density, 0.0)[r0:r0 + n, c0:c0 + n]
    path = tmp / "density.npy"
    np.save(path, density)
    starts = [[s.x - x0, s.y - y0] for s in world.starts[:robots]]
    return {"density": str(path), "resolution": res, "starts": starts, "max_steps": 2000}


def plan_command(out: Path, world: str = WORLD, robots: int = ROBOTS) -> list[str]:
    exe = Path(sys.executable).with_name("coverage-plan")
    head = [str(exe)] if exe.exists() else [sys.executable, "-m", "coverage_ros.cli.plan"]
    return head + ["--map", world, "--robots", str(robots), "--strategy", "lloyd",
                   "--solver", "lloyd", "--tolerance", str(TOLERANCE), "--max-iterations",
                   "2000", "--json", str(out)]


def bench_end_to_end(rounds: int, say, world: str = WORLD, robots: int = ROBOTS) -> dict:
    """Rounds of: our ``coverage-plan`` process, CoverageControl's run, CoverageControl's run
    with the objective every step (module docstring), on ``world`` (a name or a path) with its
    first ``robots`` starts."""
    cc_py, why = coveragecontrol_python(say)
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        req = scenario(tmp, world, robots)
        runner = str(Path(__file__).with_name("coveragecontrol_lloyd.py"))
        ours: list[dict] = []
        cc: list[dict] = []
        ratios: dict[str, list[float]] = {"step": [], "controller_step": [], "end_to_end": [],
                                          "cpu": []}
        for r in range(rounds):
            _, wall, cpu = _timed(plan_command(tmp / "plan.json", world, robots))
            plan = json.loads((tmp / "plan.json").read_text())
            mine = {"steps": plan["iterations"], "H": plan["H"],
                    "end_to_end_ms_per_step": 1e3 * wall / plan["iterations"],
                    "cpu_ms_per_step": 1e3 * cpu / plan["iterations"],
                    "step_ms": plan["update_ms"]["median"], "wall_s": wall}
            ours.append(mine)
            line = (f"  round {r + 1}/{rounds}: coverage-plan {mine['steps']} steps, "
                    f"{mine['end_to_end_ms_per_step']:.2f} ms/step end to end "
                    f"(step {mine['step_ms']:.2f} ms)")
            if cc_py is not None:
                runs = {}
                for objective in (False, True):
                    res, cc_wall, cc_cpu = _timed([cc_py, runner], json.dumps(
                        {**req, "objective": objective}))
                    runs[objective] = (json.loads(res.stdout.strip().splitlines()[-1]), cc_wall,
                                       cc_cpu)
                plain, cc_wall, cc_cpu = runs[False]
                theirs = {"steps": plain["steps"], "converged": plain["converged"],
                          "H": plain["objective"] * req["resolution"] ** 2,
                          "step_ms": 1e3 * statistics.median(plain["step_s"]),
                          "controller_step_ms": 1e3 * statistics.median(runs[True][0]["step_s"]),
                          "end_to_end_ms_per_step": 1e3 * cc_wall / plain["steps"],
                          "cpu_ms_per_step": 1e3 * cc_cpu / plain["steps"]}
                cc.append(theirs)
                for key in ("step", "controller_step"):
                    ratios[key].append(mine["end_to_end_ms_per_step"] / theirs[f"{key}_ms"])
                ratios["end_to_end"].append(mine["end_to_end_ms_per_step"]
                                            / theirs["end_to_end_ms_per_step"])
                ratios["cpu"].append(mine["cpu_ms_per_step"] / theirs["cpu_ms_per_step"])
                line += (f"; CoverageControl {theirs['steps']} steps, step "
                         f"{theirs['step_ms']:.2f} ms, with objective "
                         f"{theirs['controller_step_ms']:.2f} ms, end to end "
                         f"{theirs['end_to_end_ms_per_step']:.2f} ms/step")
            say(line)
    result: dict[str, Any]
    result = {"scenario": {"world": world, "robots": robots, "tolerance_m": TOLERANCE,
                           "command": " ".join(["coverage-plan", *plan_command(
                               Path("plan.json"), world, robots)[-14:]])},
              "rounds": rounds, "load_average_1min": [round(load_before, 2),
                                                      round(os.getloadavg()[0], 2)],
              "coverage_plan": _medians(ours)}
    if cc:
        result["coveragecontrol"] = {"version": CC_VERSION, "source": "measured here, side by "
                                     "side", **_medians(cc)}
        result["ratio_end_to_end_over"] = {k: round(statistics.median(v), 3)
                                           for k, v in ratios.items()}
        result["targets"] = [
            {"target": f"end-to-end ms/step <= CoverageControl's {what}",
             "ours": result["coverage_plan"]["end_to_end_ms_per_step"],
             "theirs": result["coveragecontrol"][key],
             "ratio": result["ratio_end_to_end_over"][ratio],
             "met": result["ratio_end_to_end_over"][ratio] <= 1}
            for what, key, ratio in (
                ("step (ComputeActions + StepActions)", "step_ms", "step"),
                ("step with the objective (ControllerCVT.step)", "controller_step_ms",
                 "controller_step"),
                ("end-to-end ms/step", "end_to_end_ms_per_step", "end_to_end"))]
        result["targets"].append({
            "target": "process CPU ms/step <= CoverageControl's (load-robust)",
            "ours": result["coverage_plan"]["cpu_ms_per_step"],
            "theirs": result["coveragecontrol"]["cpu_ms_per_step"],
            "ratio": result["ratio_end_to_end_over"]["cpu"],
            "met": result["ratio_end_to_end_over"]["cpu"] <= 1})
    else:
        result["coveragecontrol"] = {"version": CC_VERSION, "not_installed": why, **CC_RECORDED}
        result["ratio_end_to_end_over"] = {"step": round(
            result["coverage_plan"]["end_to_end_ms_per_step"] / max(CC_RECORDED["step_ms"]), 3)}
    return result


def bench_sweep(count: int, rounds: int, say) -> dict:
    """``count`` random scenarios of CoverageControl's kind (seeds from
    :data:`~coverage_ros.bench.cc_scenarios.SEEDS_FROM`), each in ``rounds`` rounds side by
    side with CoverageControl; the rows and a summary (:mod:`coverage_ros.bench.cc_scenarios`)."""
    rows = []
    with tempfile.TemporaryDirectory() as tmpdir:
        for i in range(count):
            seed = cc_scenarios.SEEDS_FROM + i
            world, robots, cells = cc_scenarios.draw(seed, i)
            path = Path(tmpdir) / f"{world['name']}.yaml"
            path.write_text(yaml.safe_dump(world))
            say(f"scenario {i + 1}/{count} (seed {seed}): {robots} robots, {cells} x {cells} "
                f"cells, {len(world['density']['components'])} Gaussians")
            result = bench_end_to_end(rounds, say, world=str(path), robots=robots)
            rows.append(cc_scenarios.row(seed, cells, world, robots, result))
            if "ratio" in rows[-1]:
                r = rows[-1]
                say(f"  end to end / CoverageControl's step: {r['ratio']:.2f} ({r['steps']} "
                    f"steps; fixed cost {r['fixed_ms']:.0f} ms: break-even at "
                    f"{r['break_even_steps']} steps); / its end to end: "
                    f"{r.get('ratio_end_to_end', float('nan')):.2f}")
    summary = cc_scenarios.summarize(rows)
    return {"seeds": [cc_scenarios.SEEDS_FROM + i for i in range(count)], "rounds": rounds,
            "targets": cc_scenarios.targets(summary), "summary": summary, "rows": rows}


def _medians(rows: list[dict]) -> dict:
    out = {}
    for key, value in rows[0].items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            out[key] = value
        else:
            out[key] = round(statistics.median(r[key] for r in rows), 4)
    return out


RESULTS = REPO / "docs" / "results" / "planner.json"


def write_results(part: str, figures: dict, path: Path, argv: list[str]) -> None:
    """Put ``figures`` under ``part`` of the results file (the other part stays), with where
    they came from."""
    from coverage_ros.bench.results import _under_test, provenance

    if _under_test():
        return
    data = json.loads(path.read_text()) if path.exists() else {}
    data[part] = {**provenance(argv), "command": "scripts/bench_planner " + " ".join(argv),
                  **figures}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1) + "\n")


def sweep_part(seed_set: str, settled: float | None, team: str = "lloyd") -> str:
    """The results file's part for a sweep of ``seed_set`` with switch threshold ``settled``
    (None: the solver's own) and the ``team`` step."""
    part = f"sweep_{seed_set.replace('-', '_')}"
    if team != "lloyd":
        part += f"_{team}"
    if settled is not None and settled != SETTLED:
        part += f"_settled_{settled:g}"
    return part


def main(argv: list[str] | None = None) -> int:
    import argparse

    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=7, help="end-to-end rounds")
    ap.add_argument("--sweep", choices=("train", "held-out", "none"), default="held-out",
                    help="the accelerated solver's sweep over random scenarios on this seed set")
    ap.add_argument("--scenarios", type=int, default=24, help="sweep scenarios")
    ap.add_argument("--team", choices=("lloyd", "geodesic"), default="lloyd",
                    help="the sweep's team step: Euclidean cells (coverage-plan --strategy "
                         "lloyd) or geodesic power cells (--strategy geodesic)")
    ap.add_argument("--settled", type=float, default=None,
                    help="the accelerated solver's switch threshold for the sweep (share of H "
                         "plain Lloyd's extrapolated tail must fall below; default the "
                         "solver's own); a sweep with another than the default is written "
                         "beside the default's, as sweep_<set>_settled_<S>")
    ap.add_argument("--e2e-scenarios", type=int, default=9,
                    help="random scenarios of CoverageControl's kind timed end to end after "
                         "gaussians (coverage_ros.bench.cc_scenarios; 0: none)")
    ap.add_argument("--e2e-rounds", type=int, default=3, help="rounds per random scenario")
    ap.add_argument("--no-end-to-end", action="store_true")
    ap.add_argument("--json", type=Path, default=RESULTS, help="results file to update")
    args = ap.parse_args(argv)
    if args.e2e_scenarios < 0 or args.e2e_rounds < 1:
        raise ConfigError.at("--e2e-scenarios / --e2e-rounds", "must be >= 0 / >= 1",
                             f"{args.e2e_scenarios} / {args.e2e_rounds}")
    if args.settled is not None and not 0.0 < args.settled < 1.0:
        raise ConfigError.at("--settled", "must be a share of H in (0, 1)", args.settled)

    def say(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    out = {}
    if not args.no_end_to_end:
        say(f"coverage-plan end to end against CoverageControl ({args.rounds} rounds)")
        e2e = bench_end_to_end(args.rounds, say)
        ours, theirs = e2e["coverage_plan"], e2e["coveragecontrol"]
        say(f"  coverage-plan: {ours['steps']} steps, {ours['end_to_end_ms_per_step']:.2f} ms "
            f"per step end to end (CPU {ours['cpu_ms_per_step']:.2f}), team step "
            f"{ours['step_ms']:.2f} ms")
        if "step_ms" in theirs and "not_installed" not in theirs:
            say(f"  CoverageControl {theirs['version']}: {theirs['steps']} steps, step "
                f"{theirs['step_ms']:.2f} ms, with the objective "
                f"{theirs['controller_step_ms']:.2f} ms, end to end "
                f"{theirs['end_to_end_ms_per_step']:.2f} ms/step")
        else:
            say(f"  CoverageControl not installed ({theirs['not_installed']}): recorded "
                f"{theirs['step_ms']} ms/step")
        say("  ours end to end / theirs (median of the rounds' ratios): " + ", ".join(
            f"{k} {v:.2f}" for k, v in e2e["ratio_end_to_end_over"].items()))
        write_results("end_to_end", e2e, args.json, argv)
        out["end_to_end"] = e2e
    if not args.no_end_to_end and args.e2e_scenarios > 0:
        say(f"coverage-plan end to end against CoverageControl on {args.e2e_scenarios} random "
            f"scenarios of its kind ({args.e2e_rounds} rounds each)")
        e2e_sweep = bench_sweep(args.e2e_scenarios, args.e2e_rounds, say)
        for t in e2e_sweep["targets"]:  # (each with its figures: ratios, steps of those missed)
            say(f"  {t['target']}: {t['value']} ({'met' if t['met'] else 'not met'})")
        write_results("end_to_end_sweep", e2e_sweep, args.json, argv)
        out["end_to_end_sweep"] = e2e_sweep
    if args.sweep != "none":
        from coverage_ros.bench.lloyd_sweep import run_sweep

        options = {} if args.settled is None else {"accelerated": {"settled": args.settled}}
        sweep = run_sweep(args.sweep, args.scenarios, say, team=args.team, **options)
        write_results(sweep_part(args.sweep, args.settled, args.team), sweep, args.json, argv)
        out["sweep"] = sweep
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
