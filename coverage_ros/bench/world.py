"""Benchmark of the world simulator's real-time factor (``scripts/bench_world``).

Steps :class:`~coverage_ros.sim.world.World` unthrottled - the code path the world node runs -
with wandering robots that turn away from what their own lidar sees, then repeats a shorter run
with the pymunk reference lidar in the same process for comparison. Progress goes to stderr;
the last line on stdout is JSON::

    {"rtf": 31.2, "robots": 16, "beams": 360, "scan_hz": 5.0, "physics_hz": 50.0, ...}
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from coverage_ros.core.world import load_world
from coverage_ros.errors import CoverageError
from coverage_ros.sim.world import SimConfig, World
from coverage_ros.worlds import resolve_world_path

REPO = Path(__file__).resolve().parents[2]
DEFAULT_WORLD = REPO.parent / "shared" / "maps" / "depot.yaml"
COMMAND_PERIOD = 0.1  # [s] sim time between commands, like a 10 Hz controller
AVOID_RANGE = 0.45  # [m] obstacle distance ahead that makes a wanderer turn
FRONT_HALF_ANGLE = 0.5  # [rad] half-width of the "ahead" sector


def _say(text: str) -> None:
    print(f"[bench_world] {text}", file=sys.stderr, flush=True)


def run(world: World, seconds: float, label: str, progress_every: float = 10.0) -> dict:
    """Drive every robot of ``world`` for ``seconds`` of sim time; returns timing figures."""
    ids = sorted(world.robots)
    front: dict[int, float] = dict.fromkeys(ids, math.inf)
    rng = np.random.default_rng(world.config.seed)
    turn = dict(zip(ids, rng.choice([-1.0, 1.0], size=len(ids)), strict=True))
    steps = round(seconds / world.config.dt)
    every = max(round(COMMAND_PERIOD / world.config.dt), 1)
    report = max(round(progress_every / world.config.dt), 1)
    scans = beams = 0
    t0 = world.time
    start = time.perf_counter()
    for k in range(steps):
        if k % every == 0:
            for i in ids:
                robot = world.robots[i]
                if front[i] < AVOID_RANGE:
                    world.set_command(i, 0.0, turn[i] * robot.spec.w_max * 0.5)
                else:
                    world.set_command(i, 0.8 * robot.spec.v_max,
                                      0.3 * math.sin(0.2 * world.time + i))
        for scan in world.step():
            lidar = world.robots[scan.robot_id].spec.lidar
            ahead = np.abs(lidar.angle_min + lidar.angle_increment * np.arange(lidar.beams))
            sector = scan.ranges[ahead < FRONT_HALF_ANGLE]
            front[scan.robot_id] = float(np.min(np.abs(sector))) if len(sector) else math.inf
            scans += 1
            beams += len(scan.ranges)
        if (k + 1) % report == 0:
            wall = time.perf_counter() - start
            _say(f"{label}: {world.time - t0:6.1f} s sim in {wall:6.2f} s wall, "
                 f"rtf {(world.time - t0) / wall:6.1f}")
    wall = time.perf_counter() - start
    return {"sim_seconds": world.time - t0, "wall_seconds": wall,
            "rtf": (world.time - t0) / wall, "scans": scans, "beams_cast": beams}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench_world", description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=16, help="number of robots (16)")
    parser.add_argument("--world", default=str(DEFAULT_WORLD),
                        help="world name or YAML path (../shared/maps/depot.yaml)")
    parser.add_argument("--seconds", type=float, default=60.0, help="sim seconds to run (60)")
    parser.add_argument("--physics-hz", type=float, default=50.0, help="physics rate (50)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--reference-seconds", type=float, default=5.0,
                        help="sim seconds with the pymunk reference lidar (5; 0: skip)")
    args = parser.parse_args(argv)
    try:
        t = time.perf_counter()
        spec = load_world(resolve_world_path(args.world, "--world"))
        config = SimConfig(seed=args.seed, physics_rate_hz=args.physics_hz)
        world = World(spec, config)
        world.populate(args.robots)
        setup_s = time.perf_counter() - t
        _say(f"world {spec.name}: {len(world.geometry.segments)} lidar segments, "
             f"{world.geometry.shape_count} static shapes, {args.robots} robots, "
             f"set up in {setup_s:.2f} s")
    except CoverageError as exc:
        print(f"bench_world: error: {exc}", file=sys.stderr)
        return 2
    lidars = {r.spec.lidar for r in world.robots.values()}
    lidar = next(iter(lidars))
    fast = run(world, args.seconds, "fast lidar")
    result = {"rtf": round(fast["rtf"], 2), "robots": args.robots, "beams": lidar.beams,
              "scan_hz": lidar.rate_hz, "physics_hz": args.physics_hz, "world": spec.name,
              "sim_seconds": round(fast["sim_seconds"], 2),
              "wall_seconds": round(fast["wall_seconds"], 3), "scans": fast["scans"],
              "map_cells": int(spec.grid.occupancy.size), "static_shapes":
              world.geometry.shape_count, "setup_seconds": round(setup_s, 2)}
    if args.reference_seconds > 0:
        ref_world = World(spec, replace(config, lidar_caster="pymunk"))
        ref_world.populate(args.robots)
        ref = run(ref_world, args.reference_seconds, "pymunk lidar (reference)",
                  progress_every=args.reference_seconds)
        result["reference_rtf"] = round(ref["rtf"], 2)
        result["speedup_vs_pymunk_lidar"] = round(fast["rtf"] / ref["rtf"], 2)
    _say(f"real-time factor {fast['rtf']:.1f} with {args.robots} robots "
         f"({fast['scans']} scans of {lidar.beams} beams)")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
