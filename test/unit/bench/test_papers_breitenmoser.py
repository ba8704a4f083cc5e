"""Breitenmoser et al. 2010 in scripts/bench_papers: the re-drawn settings, the traced team run
against run_offline, and the paper's reported values on the fast cases (the full seeds run in
the benchmark)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coverage_ros.bench.papers import breitenmoser2010 as b
from coverage_ros.bench.papers import breitenmoser2010_scenes as scenes
from coverage_ros.bench.papers import experiments
from coverage_ros.core.offline.runner import OfflineConfig, run_offline
from coverage_ros.core.strategies import StrategyContext
from coverage_ros.core.strategies.tangentbug.strategy import team_costs


def test_the_papers_values_are_registered():
    exps = {e.key: e for e in experiments(["breitenmoser"])}
    assert set(exps) == {f"breitenmoser2010/{f}" for f in ("fig2b", "fig3", "fig4", "fig5")}
    assert all(e.redrawn and e.note and e.seeds >= 5 for e in exps.values())
    # A "|" in a name or setting would split the Markdown table's cells.
    assert not any("|" in m.name or "|" in e.setting for e in exps.values() for m in e.metrics)
    fig5 = {m.name: m for m in exps["breitenmoser2010/fig5"].metrics}
    assert fig5["mean final position error against the ideal simulation"].paper_value == 5.42
    assert fig5["runs converged"].paper_value == pytest.approx(6 / 7)  # one of 7 trials lost
    assert fig5["duration of a run"].paper_value == 4.56
    assert exps["breitenmoser2010/fig5"].seeds == 7  # the paper's seven trials
    assert exps["breitenmoser2010/fig3"].slow  # a loop round the whole U takes minutes


def test_redrawn_fig2b_puts_the_centroid_in_the_bar_and_p_star_on_its_upper_face():
    spec, domain = scenes.world("fig2b")
    t = scenes.centroid(domain)
    assert not domain.is_free_point(t) and 2.0 < t[0] < 6.0 and 1.5 < t[1] < 2.4
    star = scenes.clearance_projection(spec, t, scenes.ROBOT.radius + b.FOLLOW_MARGIN)
    # The bar's upper face is y = 2.4; the density's bump at y = 2.2 lifts t above the middle.
    np.testing.assert_allclose(star, [t[0], 2.4 + scenes.ROBOT.radius + b.FOLLOW_MARGIN],
                               atol=spec.grid.resolution)


def test_fig2b_geodesic_stops_at_a_compromise_and_tangentbug_reaches_p_star():
    """Fig. 2b over three starts: geodesic Lloyd stops in the U's base, balancing the two
    branches, far from p*; tangentbug circles the boundary and ends at p* (Theorem 2)."""
    runs = [b.fig2b_one(scenes.fig2b_start(0, k)) for k in range(b.STARTS_PER_SEED)]
    assert all(r["tangentbug"] <= b.NEAR_OPTIMUM for r in runs)
    assert all(r["geodesic"] > 2.0 for r in runs)  # over twice the optimal distance


def test_traced_run_is_run_offline_and_its_virtual_cost_falls():
    """run_traced repeats run_offline step for step (it only keeps more); H of the virtual
    generators falls while the team spreads, and both costs start equal (g_virt = p_S)."""
    _, domain = scenes.world("fig4")
    starts = scenes.start_cluster(3, domain)
    trace = b.run_traced(domain, "tangentbug", starts, max_iterations=30)
    contexts = [StrategyContext(domain=domain, robot=scenes.ROBOT, robot_id=i)
                for i in range(len(starts))]
    res = run_offline(domain, "tangentbug", starts, contexts,
                      OfflineConfig(max_iterations=30, dt=b.DT))
    np.testing.assert_array_equal(trace.positions, res.positions[:-1])
    np.testing.assert_array_equal(trace.final, res.positions[-1])
    np.testing.assert_array_equal(trace.virtual[-1],
                                  [d.shared.virtual for d in res.decisions])
    H = b.cost_curves(domain, trace)
    assert H[0, 0] == H[0, 1]
    assert b.rises(H[:, 1]) == 0 and H[-1, 1] < 0.5 * H[0, 1]
    assert b.rises(np.array([3.0, 2.0, 2.0 + 1e-6, 1.0])) == 1  # and the count can see one


def test_clearance_projection_and_costs_of_a_given_partition():
    spec, domain = scenes.world("fig4")
    target = np.array([5.5, 4.2])  # in the middle block (x 4-6, y 3-5): nearest face x = 6
    clearance = scenes.ROBOT.radius + b.FOLLOW_MARGIN
    star = scenes.clearance_projection(spec, target, clearance)
    np.testing.assert_allclose(star, [6.0 + clearance, 4.2], atol=spec.grid.resolution)
    P = np.array([[2.0, 2.0], [8.0, 6.0], [2.0, 6.0]])
    h_real, _ = team_costs(domain, P, P)
    assert b.labels_cost(domain, P, P) == pytest.approx(h_real, rel=1e-9)
    assert b.labels_cost(domain, P[::-1], P) > h_real  # another partition costs more


def test_fig5_trial_matches_the_ideal_simulation_within_the_papers_error():
    """Sec. VI: e-pucks end on average 5.42 cm from the ideal simulation's positions in the
    paper; ours (safety margin and robot size only, no tracking noise) in a trial where both
    reach the same configuration, and the run is shorter than the paper's 4.56 min."""
    got = b.fig5(1)
    assert got["runs converged"] == 1.0
    assert 0.0 < got["mean final position error against the ideal simulation"] < 5.42
    assert got["duration of a run"] < 4.56
    assert math.isfinite(got["duration of a run"])
