"""Lee & Lee (IEEE Access 2024), adaptive CVT with agent dropout and reinsertion: the paper's
experiments (Sec. III-IV) side by side with its values.

Methods, on equal starts for a seed (:func:`~.lee2024_scenes.corner_cluster`):

* ``iCVT`` and ``iCVT+Projection`` - the paper's baselines (Eq. 7, Eq. 7-8);
* ``alpha-CVT as published`` - Alg. 2 with the paper's tau_drop and epsilon;
* ``alpha-CVT with relocation`` - the same plus this project's relocation once the team has
  settled (:mod:`coverage_ros.core.strategies.acvt.relocation`), the centralized default;
* ``acvt strategy`` - the decentralized ``acvt`` strategy, every robot's own update from its
  neighbours' published states, run by ``coverage-plan`` (:func:`~coverage_ros.core.offline.
  runner.run_offline`).

Each row's paper value is the one the paper reports for that method (the alpha-CVT value for
the three alpha-CVT rows). Settings are re-drawn (:mod:`.lee2024_scenes`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from coverage_ros.bench.papers import Experiment, Metric, lee2024_live
from coverage_ros.bench.papers import lee2024_scenes as scenes
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.offline.runner import OfflineConfig, run_offline
from coverage_ros.core.strategies import StrategyContext, strategy_choice
from coverage_ros.core.strategies.acvt.cells import CellSpec, MassCells, deviation_metric
from coverage_ros.core.strategies.acvt.dropout import (
    STALL_ITERATIONS,
    AcvtConfig,
    AlphaCvt,
    DropoutConfig,
)
from coverage_ros.core.strategies.acvt.relocation import RelocationConfig
from coverage_ros.core.world.robot import RobotSpec

PAPER = "Lee & Lee 2024"
ICVT, ICVT_P = "I, iCVT", "I, iCVT+Projection"
PUBLISHED, RELOCATED, STRATEGY = ("I, alpha-CVT as published", "I, alpha-CVT with relocation",
                                  "I, acvt strategy (decentralized)")
#: Iterations the decentralized runs may take (the arena scenarios settle in 20-90).
DECENTRALIZED_ITERATIONS = 300
SLOW, FAST = scenes.SLOW, scenes.FAST


PLAIN = CellSpec()  # Eq. 1


@functools.lru_cache(maxsize=64)
def _solver(domain: CoverageDomain, method: str, spec: CellSpec,
            drop_factor: float | None) -> AlphaCvt:
    # As published: Alg. 2's end tests only; with the relocation, also the stall test where
    # the targets are separate, as the acvt strategy has it (``stall_iterations: auto``).
    separate = method == "relocation" and MassCells(domain).regions > 1
    dropout = DropoutConfig(enabled=method not in ("iCVT", "iCVT+Projection"),
                            drop_factor=drop_factor,
                            stall_iterations=STALL_ITERATIONS if separate else 0)
    config = AcvtConfig(dropout=dropout, cells=spec, projection=method != "iCVT",
                        relocation=RelocationConfig(enabled=method == "relocation"))
    return AlphaCvt(domain, config)


def _centralized(domain: CoverageDomain, starts: np.ndarray, methods: tuple[str, ...],
                 speeds: np.ndarray | None = None, spec: CellSpec = PLAIN,
                 drop_factor: float | None = None) -> dict[str, float]:
    names = {"iCVT": ICVT, "iCVT+Projection": ICVT_P, "published": PUBLISHED,
             "relocation": RELOCATED}
    return {names[m]: float(_solver(domain, m, spec, drop_factor).run(starts, speeds).metric[-1])
            for m in methods}


def decentralized(domain: CoverageDomain, starts: np.ndarray,
                  speeds: np.ndarray | None = None, spec: CellSpec = PLAIN,
                  relocate: bool | str = "auto") -> float:
    """The metric at the end of a ``coverage-plan``-style run of the ``acvt`` strategy
    (``relocate=False``: its dropout as published, without the relocation or the stall test;
    the default ``auto`` relocates on separate targets, as the strategy does)."""
    k = len(starts)
    robots = [RobotSpec() for _ in range(k)] if speeds is None else \
        [RobotSpec(v_max=float(v)) for v in speeds]
    contexts = [StrategyContext(domain=domain, robot=robots[i], robot_id=i) for i in range(k)]
    params = {"visibility": spec.visibility, "scale_x": spec.scale[0], "scale_y": spec.scale[1],
              "gap_penalty": spec.gap_penalty, "relocate": relocate}
    if relocate is False:
        params["stall_iterations"] = 0
    run = run_offline(domain, strategy_choice("acvt", params), starts, contexts,
                      OfflineConfig(max_iterations=DECENTRALIZED_ITERATIONS))
    cells = MassCells(domain)
    final = run.positions[-1]
    masses, _ = cells.stats(cells.labels(final, speeds, spec), k)
    return float(deviation_metric(masses, cells.total, speeds, spec.visibility))


ALL = ("iCVT", "iCVT+Projection", "published", "relocation")
ALPHA = ("published", "relocation")


def _with_strategy(domain: CoverageDomain, starts: np.ndarray, methods: tuple[str, ...],
                   speeds: np.ndarray | None = None) -> dict[str, float]:
    out = _centralized(domain, starts, methods, speeds)
    out[STRATEGY] = decentralized(domain, starts, speeds)
    return out


# ---------------------------------------------------------------------------- Sec. III-A
def fig3(seed: int) -> dict[str, float]:
    return _with_strategy(scenes.two_targets(), scenes.corner_cluster(seed, 10), ALL)


def fig4a(seed: int) -> dict[str, float]:
    return _with_strategy(scenes.two_targets(),
                          scenes.corner_cluster(seed, 10, scenes.LOWER_RIGHT), ALPHA)


def fig4b(seed: int) -> dict[str, float]:
    return _with_strategy(scenes.two_targets(), scenes.corner_cluster(seed, 20), ALPHA)


def fig4c(seed: int) -> dict[str, float]:
    return _with_strategy(scenes.two_targets(scenes.PRIORITY), scenes.corner_cluster(seed, 10),
                          ALPHA)


def fig4d(seed: int) -> dict[str, float]:
    return _with_strategy(scenes.twin_targets(), scenes.corner_cluster(seed, 10), ALPHA)


def fig5(seed: int) -> dict[str, float]:
    return _with_strategy(scenes.bullseye(), scenes.corner_cluster(seed, 20),
                          ("iCVT+Projection",) + ALPHA)


def _fig6(domain: CoverageDomain, seed: int, counts: tuple[int, ...]) -> dict[str, float]:
    """Alpha-CVT against iCVT+P for n = 5, 10, ..., 30 from the upper-left corner."""
    wins = {m: 0 for m in ALPHA}
    out: dict[str, float] = {}
    for n in (5, 10, 15, 20, 25, 30):
        res = _centralized(domain, scenes.corner_cluster(seed, n), ("iCVT+Projection",) + ALPHA)
        for m, name in (("published", PUBLISHED), ("relocation", RELOCATED)):
            wins[m] += res[name] < res[ICVT_P]
        if n in counts:
            out.update({f"{k} (n = {n})": v for k, v in res.items()})
    out["share of n with I below iCVT+P's, alpha-CVT as published"] = wins["published"] / 6
    out["share of n with I below iCVT+P's, alpha-CVT with relocation"] = wins["relocation"] / 6
    return out


def fig6a(seed: int) -> dict[str, float]:
    return _fig6(scenes.two_targets(), seed, ())


def fig6b(seed: int) -> dict[str, float]:
    return _fig6(scenes.bullseye(), seed, (5, 10))


# ---------------------------------------------------------------------------- Sec. III-B
VISIBLE = CellSpec(visibility=True)


def _named(values: dict[str, float], metric: str) -> dict[str, float]:
    """``values`` renamed from I to the scenario's metric (I^L, I^H)."""
    return {k.replace("I,", f"{metric},", 1): v for k, v in values.items()}


def fig7(seed: int) -> dict[str, float]:
    starts = scenes.corner_cluster(seed, 10, scenes.LOWER_LEFT, arena=10.0)
    return _named(_centralized(scenes.two_walls(), starts, ("iCVT+Projection",) + ALPHA,
                               spec=VISIBLE), "I^L")


def _fig8(seed: int, drop_factor: float | None) -> dict[str, float]:
    out = {}
    for n in (25, 30):
        starts = scenes.corner_cluster(seed, n, scenes.LOWER_LEFT, arena=10.0)
        res = _centralized(scenes.two_walls(), starts, ALPHA, spec=VISIBLE,
                           drop_factor=drop_factor)
        out.update({f"{k} (n = {n})": v for k, v in _named(res, "I^L").items()})
    return out


def fig8(seed: int) -> dict[str, float]:
    return _fig8(seed, None)


def fig8_tuned(seed: int) -> dict[str, float]:
    return _fig8(seed, 1.025)


# ---------------------------------------------------------------------------- Sec. III-C, D
SHAPED = CellSpec(scale=(1.0, 0.0), gap_penalty=2.0)  # the paper's a = 1, b = 0, lambda = 2


def fig12(seed: int) -> dict[str, float]:
    return _centralized(scenes.crop_field(), scenes.corner_cluster(seed, 10), ALPHA,
                        spec=SHAPED)


def _speeds(slow: int, fast: int) -> np.ndarray:
    return np.r_[np.full(slow, SLOW), np.full(fast, FAST)]


def fig14(seed: int) -> dict[str, float]:
    starts = np.random.default_rng(seed).uniform(1.0, scenes.ARENA - 1.0, (10, 2))
    return _named(_with_strategy(scenes.two_targets(), starts, ("iCVT+Projection",) + ALPHA,
                                 _speeds(5, 5)), "I^H")


def fig15(seed: int) -> dict[str, float]:
    starts = scenes.corner_cluster(seed, 10, scenes.LOWER_LEFT, arena=10.0)
    return _named(_centralized(scenes.two_walls(), starts, ("iCVT+Projection",) + ALPHA,
                               _speeds(4, 6), VISIBLE), "I^H")


def _own(name: str) -> Callable[[int], dict[str, float]]:
    return functools.partial(own_shape_run, name)


def own_shape_run(name: str, seed: int) -> dict[str, float]:
    return _with_strategy(scenes.own_shape(name), scenes.corner_cluster(seed, 10), ALPHA)


def _base(name: str, value: float) -> Metric:
    """A baseline's metric (the paper's iCVT or iCVT + projection)."""
    return Metric(name, value, baseline=True)


def _alpha(value: float, prefix: str = "I", strategy: bool = True) -> tuple[Metric, ...]:
    names = (PUBLISHED, RELOCATED) + ((STRATEGY,) if strategy else ())
    return tuple(Metric(n.replace("I,", f"{prefix},"), value) for n in names)


def experiments() -> list[Experiment]:
    e = functools.partial(Experiment, PAPER, redrawn=True)
    rows = [
        e("Fig. 3", "two disjoint targets, 10 agents from the upper-left corner",
          (_base(ICVT, 1.2), _base(ICVT_P, 0.44)) + _alpha(0.046), fig3, key="lee2024/fig3"),
        e("Fig. 4a", "Fig. 3's targets, 10 agents from the lower-right corner", _alpha(0.076),
          fig4a, key="lee2024/fig4a"),
        e("Fig. 4b", "Fig. 3's targets, 20 agents", _alpha(0.246), fig4b, key="lee2024/fig4b"),
        e("Fig. 4c", "Fig. 3's targets with different densities (0.4, 0.9)", _alpha(0.22), fig4c,
          key="lee2024/fig4c"),
        e("Fig. 4d", "two identical targets, 10 agents", _alpha(0.039), fig4d,
          key="lee2024/fig4d"),
        e("Fig. 5", "bullseye (disc and ring), 20 agents",
          (_base(ICVT_P, 0.367),) + _alpha(0.083), fig5, key="lee2024/fig5"),
        e("Fig. 6a", "Fig. 3's targets, n = 5..30 agents",
          (Metric("share of n with I below iCVT+P's, alpha-CVT as published", 1.0, "higher"),
           Metric("share of n with I below iCVT+P's, alpha-CVT with relocation", 1.0,
                  "higher")), fig6a, key="lee2024/fig6a"),
        e("Fig. 6b", "bullseye, n = 5..30 agents",
          (_base(f"{ICVT_P} (n = 5)", 0.0576), Metric(f"{PUBLISHED} (n = 5)", 0.058),
           Metric(f"{RELOCATED} (n = 5)", 0.058), _base(f"{ICVT_P} (n = 10)", 0.12),
           Metric(f"{PUBLISHED} (n = 10)", 0.14), Metric(f"{RELOCATED} (n = 10)", 0.14),
           Metric("share of n with I below iCVT+P's, alpha-CVT as published", 4 / 6, "higher"),
           Metric("share of n with I below iCVT+P's, alpha-CVT with relocation", 4 / 6,
                  "higher")), fig6b, key="lee2024/fig6b"),
        e("Fig. 7", "two walls (10 m room of the paper's [8]), 10 agents, visible cells",
          (_base("I^L, iCVT+Projection", 0.389),) + _alpha(0.169, "I^L", False), fig7,
          key="lee2024/fig7"),
        e("Fig. 8", "two walls, n = 25 and 30 agents, visible cells",
          tuple(Metric(f"I^L, alpha-CVT {m} (n = {n})", v) for n, v in ((25, 0.392), (30, 0.346))
                for m in ("as published", "with relocation")), fig8, key="lee2024/fig8",
          slow=True),
        e("Fig. 8", "two walls, n = 25 and 30, tau_drop = 1.025 mean mass",
          tuple(Metric(f"I^L, alpha-CVT {m} (n = {n})", v) for n, v in ((25, 0.269), (30, 0.213))
                for m in ("as published", "with relocation")), fig8_tuned,
          key="lee2024/fig8-tau1.025", slow=True),
        e("Fig. 12", "crop rows, shape constraint a = 1, b = 0, lambda = 2, 10 agents",
          _alpha(0.0788, strategy=False), fig12, key="lee2024/fig12"),
        e("Fig. 14", "Fig. 3's targets, 5 + 5 agents at 0.4 / 0.8 m/s, spread starts",
          (_base("I^H, iCVT+Projection", 0.0437),) + _alpha(0.0367, "I^H"), fig14,
          key="lee2024/fig14"),
        e("Fig. 15", "two walls, 4 + 6 agents at 0.4 / 0.8 m/s, visible cells",
          (_base("I^H, iCVT+Projection", 0.402),) + _alpha(0.318, "I^H", False), fig15,
          key="lee2024/fig15"),
    ]
    live = functools.partial(Experiment, PAPER, redrawn=True, slow=True, live=True)
    collisions = Metric("collisions (both runs)", 0.0)
    rows += [
        live("Fig. 17a-c", "live team: two targets, 10 robots at 0.4 m/s from a corner",
             (_base("I, iCVT+Projection (live)", 0.444), Metric("I, alpha-CVT (live)", 0.051),
              collisions), lee2024_live.fig17_targets, key="lee2024/fig17-targets"),
        live("Fig. 17d-f", "live team: two walls, 10 robots at 0.8 m/s, visible cells",
             (_base("I^L, iCVT+Projection (live)", 0.387),
              Metric("I^L, alpha-CVT (live)", 0.187), collisions), lee2024_live.fig17_room,
             key="lee2024/fig17-room"),
        live("Fig. 18a-c", "live team: two targets, 5 + 5 robots at 0.4 / 0.8 m/s",
             (_base("I^H, iCVT+Projection (live)", 0.0701),
              Metric("I^H, alpha-CVT (live)", 0.0375), collisions), lee2024_live.fig18_targets,
             key="lee2024/fig18-targets"),
        live("Fig. 18d-f", "live team: two walls, 4 + 6 robots at 0.4 / 0.8 m/s",
             (_base("I^H, iCVT+Projection (live)", 0.4003),
              Metric("I^H, alpha-CVT (live)", 0.3305), collisions), lee2024_live.fig18_room,
             key="lee2024/fig18-room"),
    ]
    for name in scenes.OWN_SHAPES:
        rows.append(e("beyond", f"{name}, 10 agents from the upper-left corner "
                      "(our shapes; the paper's Fig. 3 value)", _alpha(0.046), _own(name),
                      key=f"lee2024/own/{name}", redrawn=False))
    return rows

