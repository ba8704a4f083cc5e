"""CoverageControl's clairvoyant Lloyd (``ClairvoyantCVT``, C++) on a given density grid: run by
:mod:`coverage_ros.bench.planner` with the interpreter of a venv that has the ``coverage-control``
wheel, never imported by this package (it needs nothing of it).

Reads a JSON request on stdin (``density``: path of an ``.npy`` (n, n) grid, rows along y;
``resolution`` [m]; ``starts`` [[x, y], ...] [m]; ``max_steps``; ``objective``: whether every step
also evaluates the objective, as CoverageControl's ``ControllerCVT.step`` does) and prints one
JSON line: steps, whether it converged, the loop's time and every step's time, the final
objective (sum of density times squared distance over the cells, no area element) and
positions.

The robots move to their centroids in one step (a speed limit far above any step), so the run is
plain Lloyd; it stops when ``ClairvoyantCVT`` says converged (no robot moves by more than
``1e-10`` m, or one sits within ``1e-4`` m of its last positions for three of the last five
steps).
"""

from __future__ import annotations

import json
import pathlib
import site
import sys
import time
import types


def _core():
    """``coverage_control._core`` without the package's ``__init__``, which imports torch for
    the learning parts (not needed, and not installed)."""
    for root in site.getsitepackages():
        path = pathlib.Path(root) / "coverage_control"
        if path.is_dir():
            pkg = types.ModuleType("coverage_control")
            pkg.__path__ = [str(path)]
            sys.modules.setdefault("coverage_control", pkg)
            import coverage_control._core as core

            return core
    raise ImportError("coverage_control is not installed in this interpreter")


def main() -> int:
    import numpy as np

    req = json.loads(sys.stdin.read())
    cc = _core()
    density = np.load(req["density"]).astype(np.float32)
    size = density.shape[0]
    params = cc.Parameters()
    params.pWorldMapSize = size
    params.pResolution = float(req["resolution"])
    params.pNumRobots = len(req["starts"])
    params.pMaxRobotSpeed = 1e6  # [m/s] one step reaches the centroid: plain Lloyd
    params.pTimeStep = 1.0
    params.pEpisodeSteps = int(req["max_steps"])
    world = cc.WorldIDF(params, np.ascontiguousarray(density.T))  # its maps are indexed (x, y)
    env = cc.CoverageSystem(params, world, cc.PointVector(req["starts"]))
    alg = cc.ClairvoyantCVT(params, env)
    step_s: list[float] = []
    objective = bool(req.get("objective", False))
    converged = False
    t0 = time.perf_counter()
    while len(step_s) < req["max_steps"] and not converged:
        t = time.perf_counter()
        alg.ComputeActions()
        converged = alg.IsConverged()
        if env.StepActions(alg.GetActions()):
            raise RuntimeError("CoverageControl refused the step")
        if objective:
            env.GetObjectiveValue()
        step_s.append(time.perf_counter() - t)
    loop = time.perf_counter() - t0
    positions = [[p[0], p[1]] for p in env.GetRobotPositions()]
    print(json.dumps({"steps": len(step_s), "converged": converged, "loop_s": loop,
                      "step_s": step_s, "objective": env.GetObjectiveValue(),
                      "positions": positions}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
