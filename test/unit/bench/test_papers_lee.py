"""Lee & Lee (2024) settings of scripts/bench_papers asserted against the paper's numbers (the
fast ones; the whole table, the slow settings and the live Figs. 17-18 are the benchmark's)."""

from __future__ import annotations

import statistics

import numpy as np
import pytest

from coverage_ros.bench.papers import lee2024
from coverage_ros.bench.papers import lee2024_scenes as scenes
from coverage_ros.core.geometry import points_in_polygon
from coverage_ros.core.strategies.acvt.cells import MassCells
from coverage_ros.core.strategies.acvt.dropout import AcvtConfig, AlphaCvt, DropoutConfig

SEEDS = range(5)


def test_fig3_targets_carry_the_mass_ratio_the_papers_numbers_fix():
    """With the masses 68 : 32, the paper's iCVT + projection split (9 + 1) has its I = 0.44 and
    the best split (7 + 3) I = 0.04, under its alpha-CVT's 0.046."""
    cells = MassCells(scenes.two_targets())
    big = cells.wdA[points_in_polygon(cells.xy, scenes.BIG)].sum()
    assert big / cells.total == pytest.approx(0.68, abs=0.005)
    k, m = 10, cells.total / 10

    def split_I(n_big: int) -> float:
        masses = [big / n_big] * n_big + [(cells.total - big) / (k - n_big)] * (k - n_big)
        return float(np.mean(np.abs(np.array(masses) / m - 1.0)))

    assert split_I(9) == pytest.approx(0.44, abs=0.01)
    assert split_I(7) == pytest.approx(0.04, abs=0.01)


def test_fig3_alpha_cvt_meets_the_paper_from_every_corner_start():
    """Paper: I = 1.2 (iCVT), 0.44 (iCVT + projection), 0.046 (alpha-CVT)."""
    domain = scenes.two_targets()
    starts = [scenes.corner_cluster(s, 10) for s in SEEDS]
    runs = [lee2024._centralized(domain, p, ("iCVT", "iCVT+Projection", "relocation"))
            for p in starts]
    ours = [r[lee2024.RELOCATED] for r in runs]
    decentralized = [lee2024.decentralized(domain, p) for p in starts[:3]]
    print(f"\nFig. 3 over {len(runs)} starts: alpha-CVT {np.round(ours, 3).tolist()}, "
          f"decentralized {np.round(decentralized, 3).tolist()}, iCVT+P "
          f"{np.round([r[lee2024.ICVT_P] for r in runs], 3).tolist()}")
    for values in (ours, decentralized):
        assert statistics.median(values) <= 0.046 and max(values) <= 2 * 0.046
    # The baselines end with the wrong split from these starts, as in the paper.
    assert min(r[lee2024.ICVT_P] for r in runs) >= 0.2
    assert min(r[lee2024.ICVT] for r in runs) >= 1.0


@pytest.mark.slow
def test_fig14_heterogeneous_agents_by_speed():
    """Paper: I^H = 0.0437 (iCVT + projection) and 0.0367 (alpha-CVT), 5 + 5 agents at 0.4 and
    0.8 m/s on the two targets. Our spread starts (re-drawn) leave iCVT + projection far worse
    (0.09-0.46). Moving one light agent at a time stopped at a balanced but unequal
    composition (four slow agents and a fast one in the small target, I^H 0.05-0.06) from three
    starts of five; the exchanges and swaps of agents of different reach (exchange.py) reach
    0.015-0.027 from all five: the median is held to the paper's value, the worst to twice it."""
    solver = AlphaCvt(scenes.two_targets())
    baseline = AlphaCvt(scenes.two_targets(), AcvtConfig(dropout=DropoutConfig(enabled=False)))
    speeds = np.r_[np.full(5, scenes.SLOW), np.full(5, scenes.FAST)]
    starts = [np.random.default_rng(s).uniform(1.0, scenes.ARENA - 1.0, (10, 2)) for s in SEEDS]
    runs = [solver.run(p, speeds) for p in starts]
    ours = [run.metric[-1] for run in runs]
    icvt = [baseline.run(p, speeds).metric[-1] for p in starts]
    print(f"\nFig. 14 I^H: alpha-CVT {np.round(ours, 3).tolist()}, iCVT+P "
          f"{np.round(icvt, 3).tolist()}")
    assert statistics.median(ours) <= 0.0367 and max(ours) <= 2 * 0.0367
    assert statistics.median(ours) < statistics.median(icvt)
    fast = runs[0]
    assert fast.masses[5:].mean() > 2.0 * fast.masses[:5].mean()  # fast agents: larger cells


@pytest.mark.slow
def test_fig14_decentralized_team_predicts_its_plans_from_a_team_that_has_levelled_off():
    """The decentralized strategy on Fig. 14's setting (the paper's alpha-CVT: I^H 0.0367).
    Its lowest-id robot predicts exchanges and swaps for the team; predicting from a team that
    counts as settled but still converges spent all four of its plans within 17 iterations
    from one start of five (I^H 0.098). Predicting once the team's metric has levelled off
    (relocation.MetricLevel), the median is held to the paper's value, the worst to twice it."""
    speeds = np.r_[np.full(5, scenes.SLOW), np.full(5, scenes.FAST)]
    starts = [np.random.default_rng(s).uniform(1.0, scenes.ARENA - 1.0, (10, 2)) for s in SEEDS]
    ours = [lee2024.decentralized(scenes.two_targets(), p, speeds) for p in starts]
    print(f"\nFig. 14 I^H, decentralized: {np.round(ours, 3).tolist()}")
    assert statistics.median(ours) <= 0.0367 and max(ours) <= 2 * 0.0367


@pytest.mark.slow
def test_fig18_setting_decentralized_team_converges_before_it_stops():
    """Fig. 18a-c's setting offline (5 + 5 agents at 0.4 / 0.8 m/s from the corner; the
    paper's live alpha-CVT: I^H 0.0375). After a swap of a slow and a fast robot Lloyd's last
    steps are 1-3 cm per update: counted converged by their step lengths, two teams of five
    stopped ``coverage-plan`` at I^H 0.09 while it was still falling. A robot is now not
    converged while the team's metric falls by the paper's epsilon over its last updates."""
    speeds = np.r_[np.full(5, scenes.SLOW), np.full(5, scenes.FAST)]
    ours = [lee2024.decentralized(scenes.two_targets(), scenes.corner_cluster(s, 10), speeds)
            for s in SEEDS]
    print(f"\nFig. 18a-c setting, decentralized, offline: I^H {np.round(ours, 3).tolist()}")
    assert statistics.median(ours) <= 0.0375 and max(ours) <= 2 * 0.0375


def test_fig4c_targets_of_different_densities_get_the_split_of_equal_masses():
    """Paper: I = 0.22 on Fig. 3's targets with densities 0.4 and 0.9 (masses nearly equal,
    so 5 + 5 agents). From one start of five the dropout ends at 4 + 6 (I 0.22); the move to
    5 + 5 lowers I to 0.06 but raises H by 4 % - H, weighted by density, prefers more agents
    on the larger, sparser target - so a relocation held to H never made it. A move between
    targets may raise H as an exchange may (relocation.DEFAULT_EXCHANGE_SLACK)."""
    domain = scenes.two_targets(scenes.PRIORITY)
    ours = [lee2024._centralized(domain, scenes.corner_cluster(s, 10), ("relocation",))
            [lee2024.RELOCATED] for s in SEEDS]
    print(f"\nFig. 4c I, alpha-CVT with relocation: {np.round(ours, 3).tolist()}")
    assert max(ours) <= 0.1 < 0.22
    final = AlphaCvt(domain).run(scenes.corner_cluster(3, 10)).positions[-1]
    cells = MassCells(domain)
    in_big = points_in_polygon(final, scenes.BIG)
    assert in_big.sum() == 5 and (cells.region_masses / cells.total).min() > 0.45


def test_fig5_bullseye_and_fig4d_twin_targets():
    """Paper: I = 0.083 on the bullseye (iCVT + projection 0.367) and 0.039 on two identical
    targets."""
    bull = lee2024._centralized(scenes.bullseye(), scenes.corner_cluster(0, 20),
                                ("iCVT+Projection", "relocation"))
    assert bull[lee2024.RELOCATED] <= 0.083 < bull[lee2024.ICVT_P]
    twin = scenes.twin_targets()
    starts = scenes.corner_cluster(0, 10)
    assert lee2024._centralized(twin, starts, ("relocation",))[lee2024.RELOCATED] <= 0.039
    assert lee2024.decentralized(twin, starts) <= 0.039


@pytest.mark.parametrize("shape", ["disc and rectangle", "strip and block", "triangle and L"])
def test_own_two_target_shapes_end_balanced_from_every_start(shape):
    """Beyond the paper's shapes: median I at or below the paper's Fig. 3
    value, worst within twice it (the published rule ends at I = 0.2 from every start on the
    strip and block: 1 + 9 instead of 2 + 8)."""
    solver = AlphaCvt(scenes.own_shape(shape))
    values = [solver.run(scenes.corner_cluster(s, 10)).metric[-1] for s in SEEDS]
    print(f"\n{shape}: I {np.round(values, 3).tolist()}")
    assert statistics.median(values) <= 0.046 and max(values) <= 2 * 0.046


def test_own_shapes_masses_split_as_drawn():
    """Each shape's targets carry the masses its agent split is meant for (the triangle and
    L's L was once drawn at 42 m^2 instead of 49: no split of ten agents could then be equal,
    and I stayed near 0.09)."""
    for name, (_, split) in scenes.OWN_SHAPES.items():
        cells = MassCells(scenes.own_shape(name))
        shares = np.sort(cells.region_masses / cells.total)
        assert shares == pytest.approx(np.sort(np.array(split) / sum(split)), abs=0.005), name


def test_strip_and_block_settle_into_equal_cells_from_every_start():
    """The strip (2 agents) and the block (8) have CVTs of exactly equal cells and CVTs a few
    percent off. Moving a light agent only to the far point of a heavy cell rebuilt the same
    CVT (I 0.03-0.04 from three starts of five); the step halfway into the heavy neighbour's
    cell (relocation.nudge_point) lets the team settle into the equal one from every start."""
    domain = scenes.own_shape("strip and block")
    values = [lee2024._centralized(domain, scenes.corner_cluster(s, 10), ("relocation",))
              [lee2024.RELOCATED] for s in SEEDS]
    print(f"\nstrip and block: I {np.round(values, 3).tolist()}")
    assert max(values) <= 0.005


def test_live_room_starts_are_ones_the_launcher_accepts(tmp_path):
    """The live Figs. 17d-f / 18d-f draw their start clusters near the room's first wall: every
    seed's starts keep the robots' bodies clear of the walls and of each other (a seed of the
    first bench run put one inside the wall, and the launcher refused the run)."""
    import yaml

    from coverage_ros.bench.papers import lee2024_live
    from coverage_ros.core.world import load_world
    from coverage_ros.core.world.placement import validate_starts
    from coverage_ros.errors import ConfigError

    path = tmp_path / "room.yaml"
    path.write_text(yaml.safe_dump(lee2024_live._room_world()))
    world = load_world(path)
    for seed in range(10):
        starts = scenes.corner_cluster(seed, 10, scenes.LOWER_LEFT, arena=lee2024_live.ROOM_SIDE,
                                       keep=lee2024_live._clear_of_walls)
        validate_starts(world, starts, [scenes.TB3_RADIUS] * 10, f"seed {seed}")
    unchecked = scenes.corner_cluster(1, 10, scenes.LOWER_LEFT, arena=lee2024_live.ROOM_SIDE)
    with pytest.raises(ConfigError, match="inside an obstacle or wall"):
        validate_starts(world, unchecked, [scenes.TB3_RADIUS] * 10, "seed 1")
