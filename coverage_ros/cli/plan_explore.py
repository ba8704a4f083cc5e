"""``coverage-plan --explore``: a team explores the map offline, from nothing.

The robots' own controllers run on the offline simulator
(:func:`~coverage_ros.core.offline.exploration.run_exploration`: unicycles at their speed
limits, lidar scans of the true map, a shared belief), so its sim times compare with a live
team's. Reports the same ``exploration`` fields as ``coverage-team --explore``, writes the
team's belief as ``explored_map.yaml`` + ``.pgm`` beside the JSON (or the PNG), and draws the
belief with its entropy under the final cells.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from coverage_ros.core.exploration.maps import belief_grid, trinary_grid
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tessellation import Generator, tessellate
from coverage_ros.core.offline.exploration import ExplorationConfig, run_exploration
from coverage_ros.core.strategies import StrategyChoice
from coverage_ros.core.world.map_server import write_map_yaml
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.core.world.spec import WorldSpec

#: [s] between the progress lines.
PROGRESS_PERIOD = 20.0


def plan_exploration(args, world: WorldSpec, path: Path, choice: StrategyChoice,
                     specs: list[RobotSpec], starts: np.ndarray, say) -> dict:
    """Run, report and write the outputs of one offline exploration (see module docstring)."""
    config = ExplorationConfig(duration=args.duration, until_explored=args.until_explored)
    say(f"coverage-plan: exploring {path} with {len(specs)} x {choice.name} "
        f"({world.grid.width} x {world.grid.height} cells), at most {args.duration:g} s")
    t0 = time.perf_counter()

    def progress(t: float, explored: float) -> None:
        if t % PROGRESS_PERIOD < 1e-6:
            say(f"  t = {t:5.0f} s: explored {100 * explored:5.1f} %")

    run = run_exploration(world.grid, choice, starts, specs, config, args.connectivity,
                          progress)
    final = run.positions[-1]
    radius = max(s.radius for s in specs)
    truth = CoverageDomain.from_grid(world.grid, radius, world.density)
    weights = [s.power_weight for s in specs]
    H = tessellate(truth, [Generator(p, w) for p, w in zip(final, weights, strict=True)]).cost
    summary = {
        "map": str(path), "strategy": choice.name, "explore": True, "robots": len(specs),
        "start_positions": np.asarray(starts)[:, :2].round(4).tolist(),
        "positions": final.round(4).tolist(), "sim_time": round(run.sim_time, 2),
        "H": float(H), "collisions": run.collisions,
        "min_separation": round(run.min_separation, 4), "converged": run.converged,
        "exploration": {
            "explored_fraction": round(float(run.explored[-1]), 4),
            "false_free": round(float(run.false_free[-1]), 5),
            "explored_at": run.explored_at,
            "series": [[round(float(t), 2), round(float(e), 4), round(float(f), 5)]
                       for t, e, f in zip(run.times, run.explored, run.false_free,
                                          strict=True)]},
        "wall_time_s": round(time.perf_counter() - t0, 3),
    }
    at95 = run.explored_at["0.95"]
    say(f"  explored {100 * run.explored[-1]:.1f} % in {run.sim_time:.0f} s sim time "
        f"({'95 % not reached' if at95 is None else f'95 % at {at95} s'}), false free "
        f"{100 * run.false_free[-1]:.2f} %, {run.collisions} collisions")
    out = next((p.parent for p in (args.json, args.png) if p is not None), None)
    if out is not None:
        summary["explored_map"] = str(write_map_yaml(trinary_grid(run.snapshot),
                                                     out / "explored_map.yaml"))
        say(f"  wrote {summary['explored_map']}")
    if args.png:
        from coverage_ros.viz.png import render_plan

        found = belief_grid(run.snapshot)
        known = CoverageDomain.from_grid(found, radius, unknown_is_free=False)
        labels = tessellate(known, [Generator(p) for p in final]).labels
        render_plan(found, labels, run.positions, args.png,
                    title=f"exploring, {choice.name}: {len(specs)} robots, "
                    f"{100 * run.explored[-1]:.0f} % in {run.sim_time:.0f} s",
                    underlay=run.snapshot.entropy / np.log(2.0))
        say(f"  wrote {args.png}")
    return summary
