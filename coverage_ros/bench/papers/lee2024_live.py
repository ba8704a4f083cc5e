"""Lee & Lee (2024) Sec. IV on the live team: Figs. 17-18, real-time coverage with mobile robots.

The paper runs Alg. 3 (its goals every second, A* + RVO on TurtleBot3 models in Unity/ROS); here
the live ``coverage-team`` in lock-step (the same seed gives the same row): the world node
simulates the robots, each ``robot_node`` runs the decentralized ``acvt`` strategy (its own
planner and safety filter), iCVT + projection being the same strategy with ``dropout: false``.
The robots are TurtleBot3-like bodies with the paper's top speeds (0.4 m/s, or 0.4 / 0.8 m/s for
the heterogeneous Fig. 18), starting in a corner cluster
(:func:`~.lee2024_scenes.corner_cluster`); the metric is computed from the final positions on
the same grid as offline: I (Eq. 9) on the two targets, I^L (Eq. 13) in the walled room, I^H
(Eq. 18) for mixed speeds.
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import yaml

from coverage_ros.bench.papers import lee2024_scenes as scenes
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.strategies.acvt.cells import CellSpec, MassCells, deviation_metric
from coverage_ros.core.world import WorldSpec, load_world

#: [s] simulated time of a run: long enough for the relocations a corner start needs (each waits
#: for the team to settle, then crosses the arena at 0.4 m/s).
DURATION = 240.0
#: Robots per robot process (the launcher's composition): ten robots in two processes.
ROBOTS_PER_PROCESS = 5
#: [m] robots stop this near their goals (robot parameter ``arrival_tolerance``; the default
#: 5 cm leaves Lloyd's last steps undone).
ARRIVAL_TOLERANCE = 0.02
WORLD_RESOLUTION = 0.1  # [m] as the offline domains
#: The walled room of Figs. 7 / 17d (10 m, two walls of 20 cm) as world obstacles.
ROOM_SIDE = 10.0  # [m]
ROOM_WALLS = ({"type": "box", "center": [3.25, 3.5], "size": [6.5, 0.2]},
              {"type": "box", "center": [6.75, 6.5], "size": [6.5, 0.2]})
START_CLEARANCE = 0.05  # [m] between a start's body and a wall


def _clear_of_walls(p: np.ndarray) -> bool:
    """Whether a robot body at ``p`` keeps clear of the room's walls (a start cluster drawn near
    the first wall may otherwise put a robot inside it, which the launcher refuses)."""
    for wall in ROOM_WALLS:
        half = np.asarray(wall["size"]) / 2.0
        gap = np.maximum(np.abs(p - np.asarray(wall["center"])) - half, 0.0)
        if math.hypot(*gap) < scenes.TB3_RADIUS + START_CLEARANCE:
            return False
    return True


def _targets_world() -> dict:
    polys = [scenes.BIG.round(3).tolist(), scenes.SMALL.round(3).tolist()]
    return {"name": "lee_two_targets", "resolution": WORLD_RESOLUTION,
            "bounds": [0.0, 0.0, scenes.ARENA, scenes.ARENA],
            "density": {"type": "targets", "polygons": polys}}


def _room_world() -> dict:
    return {"name": "lee_two_walls", "resolution": WORLD_RESOLUTION,
            "bounds": [0.0, 0.0, ROOM_SIDE, ROOM_SIDE], "obstacles": list(ROOM_WALLS)}


def _team(starts: np.ndarray, speeds: np.ndarray) -> dict:
    return {"robots": [{"id": i, "start": [round(float(x), 3), round(float(y), 3), 0.0],
                        "v_max": float(v)} for i, ((x, y), v) in enumerate(zip(starts, speeds,
                                                                                 strict=True))]}


def run_live(world: dict, starts: np.ndarray, speeds: np.ndarray, params: dict,
             duration: float = DURATION, seed: int = 0,
             rtf: float | None = None) -> tuple[np.ndarray, WorldSpec, int]:
    """Run ``coverage-team`` with the ``acvt`` strategy (``params``) on ``world`` (a world
    mapping) from ``starts (k, 2)`` at ``speeds (k,)`` [m/s]: the final positions ``(k, 2)``,
    the world and the number of collisions."""
    from coverage_ros.cli.team import main as team_main

    with tempfile.TemporaryDirectory(prefix="lee-live-") as tmp:
        folder = Path(tmp)
        (folder / "world.yaml").write_text(yaml.safe_dump(world))
        (folder / "team.yaml").write_text(yaml.safe_dump(_team(starts, speeds)))
        out = folder / "run"
        code = team_main(["--world", str(folder / "world.yaml"), "--team",
                          str(folder / "team.yaml"), "--strategy", "acvt",
                          "--strategy-params", json.dumps(params), "--duration", str(duration),
                          "--seed", str(seed),
                          *(["--lockstep"] if rtf is None else ["--rtf", str(rtf)]),
                          "--robots-per-process",
                          str(ROBOTS_PER_PROCESS), "--robot-param",
                          f"arrival_tolerance:={ARRIVAL_TOLERANCE}", "--no-markers", "--quiet",
                          "--out", str(out)])
        if code != 0:
            raise RuntimeError(f"coverage-team ended with exit code {code}")
        summary = json.loads((out / "summary.json").read_text())
        world_spec = load_world(folder / "world.yaml")
    final = {r["id"]: r["final"][:2] for r in summary["robots"]}
    collisions = sum(int(r["collisions"]) for r in summary["robots"])
    return np.array([final[i] for i in range(len(starts))], np.float64), world_spec, collisions


def live_metric(world: dict, starts: np.ndarray, speeds: np.ndarray, params: dict,
                spec: CellSpec, heterogeneous: bool, seed: int,
                rtf: float | None = None) -> tuple[float, int]:
    """The paper's metric (I, I^L or I^H) at the end of a live run, and its collisions."""
    final, world_spec, collisions = run_live(world, starts, speeds, params, seed=seed, rtf=rtf)
    domain = world_domain(world_spec, scenes.TB3_RADIUS)
    cells = MassCells(domain)
    reach = speeds if heterogeneous else None
    masses, _ = cells.stats(cells.labels(final, reach, spec), len(final))
    return float(deviation_metric(masses, cells.total, reach, spec.visibility)), collisions


SLOW, FAST = scenes.SLOW, scenes.FAST


#: The methods a live figure runs side by side, as in the paper: (name, ``strategy_params``).
METHODS: tuple[tuple[str, dict[str, object]], ...] = (
    ("iCVT+Projection", {"dropout": False}), ("alpha-CVT", {}))


def _fig(world: dict, starts: np.ndarray, speeds: np.ndarray, visible: bool, metric: str,
         seed: int, methods: tuple[str, ...] | None = None,
         rtf: float | None = None) -> dict[str, float]:
    spec = CellSpec(visibility=visible)
    hetero = bool(np.ptp(speeds) > 0)
    out: dict[str, float] = {}
    collisions = 0
    for name, params in METHODS:
        if methods is not None and name not in methods:
            continue
        value, hits = live_metric(world, starts, speeds, {**params, "visibility": visible},
                                  spec, hetero, seed, rtf)
        out[f"{metric}, {name} (live)"] = value
        collisions += hits
    out["collisions (both runs)" if methods is None else "collisions"] = float(collisions)
    return out


def fig17_targets(seed: int, methods: tuple[str, ...] | None = None,
                  rtf: float | None = None) -> dict[str, float]:
    return _fig(_targets_world(), scenes.corner_cluster(seed, 10), np.full(10, SLOW), False,
                "I", seed, methods, rtf)


def fig17_room(seed: int, methods: tuple[str, ...] | None = None,
               rtf: float | None = None) -> dict[str, float]:
    starts = scenes.corner_cluster(seed, 10, scenes.LOWER_LEFT, arena=ROOM_SIDE,
                                   keep=_clear_of_walls)
    return _fig(_room_world(), starts, np.full(10, FAST), True, "I^L", seed, methods, rtf)


def fig18_targets(seed: int, methods: tuple[str, ...] | None = None,
                  rtf: float | None = None) -> dict[str, float]:
    speeds = np.r_[np.full(5, SLOW), np.full(5, FAST)]
    return _fig(_targets_world(), scenes.corner_cluster(seed, 10), speeds, False, "I^H", seed,
                methods, rtf)


def fig18_room(seed: int, methods: tuple[str, ...] | None = None,
               rtf: float | None = None) -> dict[str, float]:
    speeds = np.r_[np.full(4, SLOW), np.full(6, FAST)]
    starts = scenes.corner_cluster(seed, 10, scenes.LOWER_LEFT, arena=ROOM_SIDE,
                                   keep=_clear_of_walls)
    return _fig(_room_world(), starts, speeds, True, "I^H", seed, methods, rtf)


FIGURES = {"fig17-targets": fig17_targets, "fig17-room": fig17_room,
           "fig18-targets": fig18_targets, "fig18-room": fig18_room}


def main(argv: list[str] | None = None) -> int:
    """One live figure's runs for some methods only (``bench_papers`` runs them all): e.g. the
    alpha-CVT runs again after a change to the dropout, which iCVT + projection does not run."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m coverage_ros.bench.papers.lee2024_live",
                                 description=main.__doc__)
    ap.add_argument("figure", choices=sorted(FIGURES))
    ap.add_argument("--methods", default=",".join(name for name, _ in METHODS),
                    help="comma-separated, of: " + ", ".join(name for name, _ in METHODS))
    ap.add_argument("--seeds", type=int, default=5,
                    help="N seeds, the same starts as bench_papers' (default 5)")
    ap.add_argument("--rtf", type=float, default=None,
                    help="run the team in real time at this factor instead of lock-step (to "
                    "see what the machine's load does to a run)")
    ap.add_argument("--first-seed", type=int, default=0,
                    help="seed to begin with (default 0; bench_papers runs 0..4)")
    args = ap.parse_args(argv)
    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    known = {name for name, _ in METHODS}
    if not methods or not set(methods) <= known:
        ap.error(f"--methods {args.methods!r}: expected some of {sorted(known)}")
    rows = []
    if args.seeds < 1 or args.first_seed < 0:
        ap.error(f"--seeds {args.seeds} / --first-seed {args.first_seed}: expected >= 1 / >= 0")
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        values = FIGURES[args.figure](seed, methods, args.rtf)
        print(f"{args.figure} seed {seed + 1}: " + ", ".join(
            f"{k} {v:.4g}" for k, v in values.items()), flush=True)
        rows.append({"seed": seed, **values})
    print(json.dumps({"figure": args.figure, "runs": rows}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
