"""Lee & Lee 2024 (alpha-CVT): metrics, cells, dropout, and the paper's scenarios.

Scenario domains are 200 x 200 cells like the paper's (0.1 m cells: the 20 m x 20 m arena of
its real-time section), with the TurtleBot3 radius inflating the arena walls:

* two disjoint targets, 10 agents starting in the upper-left corner (paper Fig. 3): a 9 x 6 m
  and a 6 x 6 m rectangle, so the balanced split is 6 + 4 agents (3 x 2 and 2 x 2 CVTs of
  equal cells). The paper's shapes are not given; with a split that cannot be balanced, even
  a perfect split leaves an I set by Lloyd's unequal cells inside one target (a 7-agent CVT of
  a 4:3 rectangle alone has I = 0.14), which would test Lloyd, not the dropout.
* a bullseye (paper Fig. 5): a disc of radius 2.5 m and a ring 5 - 7.5 m about the centre,
  20 agents from the upper-left corner.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.metrics import mass_deviation
from coverage_ros.core.offline.runner import OfflineConfig, run_offline
from coverage_ros.core.strategies import (
    Neighbour,
    Observation,
    SharedState,
    StrategyContext,
    make_strategy,
    strategy_choice,
)
from coverage_ros.core.strategies.acvt.cells import (
    CellSpec,
    MassCells,
    deviation_metric,
    gap_lengths,
    heterogeneous_deviation,
    uncovered_deviation,
    visible_mass_deviation,
)
from coverage_ros.core.strategies.acvt.dropout import (
    STALL_ITERATIONS,
    AcvtConfig,
    AlphaCvt,
    DropoutConfig,
    DropoutSwitch,
    greedy_mask,
)
from coverage_ros.core.world.density import TargetPolygons, UniformDensity
from coverage_ros.core.world.grid import OCCUPIED, GridMap
from coverage_ros.errors import ConfigError

RES = 0.1  # [m] per cell: 200 cells = the paper's 20 m arena
TB3_RADIUS = 0.105  # [m]
BIG = np.array([[10.0, 10.0], [19.0, 10.0], [19.0, 16.0], [10.0, 16.0]])  # 9 x 6 m
SMALL = np.array([[2.0, 1.5], [8.0, 1.5], [8.0, 7.5], [2.0, 7.5]])  # 6 x 6 m
#: Spread of I among converged configurations with the balanced 6 + 4 split on this grid
#: (0.000 - 0.024 measured over nine starts): below it, ratios of I compare grid noise.
I_GRID_FLOOR = 0.025


def arena(n: int = 200, occupancy: np.ndarray | None = None, density=None,
          radius: float = TB3_RADIUS) -> CoverageDomain:
    occ = np.zeros((n, n), np.int8) if occupancy is None else occupancy
    return CoverageDomain.from_grid(GridMap(occ, RES), radius, density or UniformDensity())


def corner(n: int, origin=(0.6, 19.4), step: float = 0.35, up: bool = False) -> np.ndarray:
    """``(n, 2)`` [m]: a square cluster growing right and down (or up) from ``origin``."""
    cols = math.ceil(math.sqrt(n))
    dy = step if up else -step
    return np.array([(origin[0] + step * (i % cols), origin[1] + dy * (i // cols))
                     for i in range(n)])


def inside(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    return np.all((pts >= lo) & (pts <= hi), axis=1)


def final_deviation(domain: CoverageDomain, positions: np.ndarray) -> float:
    cells = MassCells(domain)
    masses, _ = cells.stats(cells.labels(positions), len(positions))
    return mass_deviation(masses)


@pytest.fixture(scope="module")
def two_targets() -> CoverageDomain:
    return arena(density=TargetPolygons((BIG, SMALL)))


@pytest.fixture(scope="module")
def bullseye() -> CoverageDomain:
    dom = arena()
    X, Y = dom.geometry.all_cell_centers()
    r = np.hypot(X - 10.0, Y - 10.0)
    return dom.with_density(((r <= 2.5) | ((r >= 5.0) & (r <= 7.5))).astype(float))


@pytest.fixture(scope="module")
def two_target_runs(two_targets):
    starts = corner(10)
    acvt = AlphaCvt(two_targets).run(starts)
    icvt = AlphaCvt(two_targets, AcvtConfig(dropout=DropoutConfig(enabled=False))).run(starts)
    return starts, acvt, icvt


@pytest.fixture(scope="module")
def bullseye_runs(bullseye):
    starts = corner(20)
    acvt = AlphaCvt(bullseye).run(starts)
    icvt = AlphaCvt(bullseye, AcvtConfig(dropout=DropoutConfig(enabled=False))).run(starts)
    return starts, acvt, icvt


# ---------------------------------------------------------------------------- metrics
def test_mass_deviation_eq9_hand_case():
    # mean 2: |0.5 - 1| + |1 - 1| + |1.5 - 1| = 1, over k = 3
    assert mass_deviation([1.0, 2.0, 3.0]) == pytest.approx(1.0 / 3.0)
    assert mass_deviation([4.0, 4.0, 4.0, 4.0]) == 0.0
    # one agent holds everything: (|4 - 1| + 3 * |0 - 1|) / 4
    assert mass_deviation([8.0, 0.0, 0.0, 0.0]) == pytest.approx(1.5)


def test_uncovered_deviation_eq14_and_eq13_hand_case():
    # total 5, covered 2 + 2: I_c = (5 - 4) / (k * mean) = 1 / 4
    assert uncovered_deviation(np.array([2.0, 2.0]), 5.0) == pytest.approx(0.25)
    assert uncovered_deviation(np.array([2.0, 2.0]), 4.0) == 0.0
    assert uncovered_deviation(np.array([0.0, 0.0]), 4.0) == math.inf
    # masses 1.8 / 2.2 of total 8: I = 0.1, I_c = 4 / 4, I^L = 1.1
    assert visible_mass_deviation(np.array([1.8, 2.2]), 8.0) == pytest.approx(1.1)


def test_visible_cells_eq12_and_metric_eq13_on_a_walled_grid():
    """A full wall splits a 20 x 41 grid; both agents stand on the left. Their Voronoi cells
    reach across the wall, but only the visible halves count (Eq. 12): 9 and 11 rows of 20
    cells of 0.01 m^2, and the right half (8 m^2 - 4 m^2) is uncovered."""
    occ = np.zeros((20, 41), np.int8)
    occ[:, 20] = OCCUPIED
    dom = CoverageDomain.from_grid(GridMap(occ, RES), 0.0)
    cells = MassCells(dom)
    P = np.array([[1.0, 0.5], [1.0, 1.3]])  # bisector y = 0.9: rows 0-8 vs rows 9-19
    blind = cells.labels(P)
    seeing = cells.labels(P, spec=CellSpec(visibility=True))
    m_blind, _ = cells.stats(blind, 2)
    m_seen, _ = cells.stats(seeing, 2)
    assert m_blind == pytest.approx([9 * 40 * 0.01, 11 * 40 * 0.01])
    assert m_seen == pytest.approx([9 * 20 * 0.01, 11 * 20 * 0.01])
    assert cells.total == pytest.approx(8.0)
    assert np.all(seeing[cells.xy[:, 0] > 2.05] == -1)
    assert deviation_metric(m_seen, cells.total, None, True) == pytest.approx(0.1 + 1.0)


def test_heterogeneous_metric_eq18_hand_case():
    # masses proportional to R^2 are balanced
    assert heterogeneous_deviation(np.array([1.0, 4.0]), np.array([1.0, 2.0]), 5.0) == 0.0
    # equal masses, R = 1 and 2: M^h = (1, 1/4) / pi, mean 5 / (8 pi): |1.6 - 1| = |0.4 - 1|
    assert heterogeneous_deviation(np.array([1.0, 1.0]), np.array([1.0, 2.0]),
                                   2.0) == pytest.approx(0.6)


# ---------------------------------------------------------------------------- cells
def test_projection_eq8_moves_goals_onto_the_nearest_target_cell():
    target = np.array([[1.0, 1.0], [2.0, 1.0], [2.0, 2.0], [1.0, 2.0]])
    cells = MassCells(arena(40, density=TargetPolygons((target,)), radius=0.0))
    out = cells.project(np.array([[1.5, 1.5], [0.2, 1.43], [3.5, 3.5], [-5.0, 1.5]]))
    assert out[0] == pytest.approx([1.5, 1.5])  # already on rho > 0: unchanged
    assert out[1] == pytest.approx([1.05, 1.45])  # the nearest target cell's centre
    assert out[2] == pytest.approx([1.95, 1.95])
    assert out[3] == pytest.approx([1.05, 1.55])  # off the grid: clipped to it, then moved
    # An agent with an empty cell projects its own position into the target (iCVT+P).
    step = AlphaCvt(cells.domain).cvt_step(np.array([[1.5, 1.5], [3.8, 3.8]]), None)
    assert step[1] == pytest.approx([1.95, 1.95])


def test_plain_partition_matches_the_obvious_one(rng):
    """The matrix-product Voronoi labels equal the running-minimum ones (reach 1 for all,
    the general path), and coincident agents leave the shared cell to the lowest index."""
    cells = MassCells(arena(60, radius=0.0))
    P = rng.uniform(0.0, 6.0, (9, 2))
    P[5] = P[2]
    fast = cells.labels(P)
    assert np.array_equal(fast, cells.labels(P, np.ones(9)))
    assert not np.any(fast == 5) and np.any(fast == 2)
    d2 = ((cells.xy[:, None, :] - P[None]) ** 2).sum(-1)
    assert np.array_equal(fast, np.argmin(d2, axis=1))


def test_partition_over_reaches_matches_the_running_minimum(rng):
    """The vectorized labels of agents of mixed reach (Eq. 17) equal a running minimum of
    :meth:`MassCells.distance` agent by agent, ties (coincident agents of one reach) to the
    lowest index, but where two agents' distances are equal to rounding (the expanded squares
    round otherwise); with and without visibility."""
    cells = MassCells(arena(60, radius=0.0))
    for trial in range(12):
        k = int(rng.integers(2, 16))
        P = rng.uniform(0.0, 6.0, (k, 2))
        R = rng.choice([0.22, 0.4, 0.8], k)
        if trial % 3 == 0:
            P[1], R[1] = P[0], R[0]
        best, slow = np.full(len(cells.nodes), np.inf), np.zeros(len(cells.nodes), np.int64)
        for i, p in enumerate(P):
            d = cells.distance(p, R[i], CellSpec())
            slow[d < best] = i
            best = np.minimum(best, d)
        fast = cells.labels(P, R)
        differ = np.flatnonzero(fast != slow)
        assert len(differ) <= 2
        d = np.array([cells.distance(P[i], R[i], CellSpec(), differ) for i in range(k)])
        at = np.arange(len(differ))
        assert np.allclose(d[fast[differ], at], d[slow[differ], at], rtol=1e-12, atol=0.0)
        assert np.array_equal(cells.labels(P, R, CellSpec(visibility=True)),
                              cells.restrict_to_visible(fast, P))


def test_heterogeneous_cells_eq17_are_apollonius_regions():
    """With reaches 1 and 2 the boundary on the line between agents 3 m apart is 1 m from the
    slow agent (|s - p1| / 1 = |s - p2| / 2), not 1.5 m."""
    cells = MassCells(arena(60, radius=0.0))
    P = np.array([[1.5, 3.05], [4.5, 3.05]])
    on_line = np.isclose(cells.xy[:, 1], 3.05)
    x = cells.xy[on_line, 0]
    lab = cells.labels(P, np.array([1.0, 2.0]))[on_line]
    between = (x > 1.5) & (x < 4.5)
    assert np.all(lab[between & (x < 2.45)] == 0)
    assert np.all(lab[between & (x > 2.55)] == 1)
    # The slow agent's region is the disc about (0.5, 3.05) of radius 2 m; the corner cell is
    # nearer to it (3.33 m vs 5.37 m) but outside that disc: the fast agent's.
    corner_cell = np.flatnonzero(np.all(np.isclose(cells.xy, 0.05), axis=1))
    assert cells.labels(P, np.array([1.0, 2.0]))[corner_cell].tolist() == [1]
    assert cells.labels(P)[corner_cell].tolist() == [0]


def test_gap_lengths_hand_cases():
    zero = np.zeros((40, 40), bool)
    zero[10:15, :] = True  # a band of rho = 0, 5 cells high
    origin = np.array([5.5, 2.5])
    pts = np.array([[5.5, 30.5], [5.5 + 28.0, 30.5], [5.5, 8.5]])
    got = gap_lengths(zero, origin, pts)
    assert got[0] == pytest.approx(5.0, abs=0.5)
    assert got[1] == pytest.approx(5.0 * math.sqrt(2.0), abs=0.75)  # crossing at 45 deg
    assert got[2] == pytest.approx(0.0, abs=1e-12)


def test_shape_constraint_eq15():
    """a = 1, b = 0 ignores vertical distances (cells become vertical strips); the gap
    penalty lambda then keeps a cell with the agent on its own side of a rho = 0 band."""
    lower = np.array([[0.2, 0.2], [3.8, 0.2], [3.8, 1.4], [0.2, 1.4]])
    upper = np.array([[0.2, 2.6], [3.8, 2.6], [3.8, 3.8], [0.2, 3.8]])
    cells = MassCells(arena(40, density=TargetPolygons((lower, upper)), radius=0.0))
    P = np.array([[1.0, 0.8], [2.2, 3.2]])
    strips = cells.labels(P, spec=CellSpec(scale=(1.0, 0.0)))
    x = cells.xy[:, 0]
    assert np.all(strips[x < 1.55] == 0) and np.all(strips[x > 1.65] == 1)
    rows = cells.labels(P, spec=CellSpec(scale=(1.0, 0.0), gap_penalty=2.0))
    y = cells.xy[:, 1]
    # crossing the 1.2 m band costs lambda * l >= 2.4 m, more than the horizontal advantage
    # of the other agent (at most 1.2 m, their x distance): each agent keeps its own row
    assert np.all(rows[y < 2.0] == 0) and np.all(rows[y > 2.0] == 1)
    with pytest.raises(ConfigError, match="scale"):
        CellSpec(scale=(0.0, 0.0))


# ---------------------------------------------------------------------------- dropout
def test_greedy_mask_alg1_threshold():
    # k = 4, mean 1.5, tau = 4/3 * 1.5 = 2: only the agent with 3 is greedy
    assert greedy_mask(np.array([1.0, 1.0, 1.0, 3.0])).tolist() == [False] * 3 + [True]
    # M_i >= tau counts (mean 1.5, tau 2)
    assert greedy_mask(np.array([2.0, 1.0, 1.5, 1.5])).tolist() == [True, False, False, False]
    assert not greedy_mask(np.full(5, 2.0)).any()  # balanced: nobody
    assert not greedy_mask(np.array([3.0])).any()
    assert greedy_mask(np.array([1.0, 1.0, 1.0, 3.0]), drop_factor=1.1).tolist() == [
        False, False, False, True]


def test_dropout_switch_ends_a_limit_cycle_that_the_filter_would_keep_for_long():
    # Fig. 3's pattern: a big first Delta I (out of the corner), then I swinging between two
    # values. The filter alone (gain 0.2) stays above epsilon for ~28 samples.
    trace = [1.2, 0.7, 0.3, 0.1, 0.05] + [0.046, 0.042] * 20
    alone = DropoutSwitch(DropoutConfig(stall_iterations=0))
    on_filter = next(i for i, m in enumerate(trace) if not alone.update(m))
    assert on_filter > 25
    switch = DropoutSwitch(DropoutConfig(stall_iterations=5))
    ends = next(i for i, m in enumerate(trace) if not switch.update(m))
    # Samples 5 (0.046 < 0.05 - 0.002) and 6 (0.042 < 0.046 - 0.002) are the last new lows by
    # epsilon; the dropout ends at the fifth sample without one.
    assert ends == 6 + 5
    # A team that keeps improving by more than epsilon per sample is never stopped by it.
    steady = DropoutSwitch(DropoutConfig(stall_iterations=5, filter_gain=1.0))
    assert all(steady.update(2.0 - 0.01 * i) for i in range(100))
    # A new low counts once it is epsilon below the last: 0.001 per sample makes one every
    # third sample (a first Delta I of 1 and a tiny gain keep the filter out of the way).
    slow = [2.0] + [1.0 - 0.001 * i for i in range(30)]
    assert all(DropoutSwitch(DropoutConfig(stall_iterations=3, filter_gain=1e-6)).update(m)
               for m in slow)
    two = DropoutSwitch(DropoutConfig(stall_iterations=2, filter_gain=1e-6))
    assert [two.update(m) for m in slow[:4]] == [True, True, True, False]
    with pytest.raises(ConfigError, match="stall_iterations"):
        DropoutConfig(stall_iterations=-1)
    with pytest.raises(ConfigError, match="stall_iterations"):
        DropoutConfig(stall_iterations=2.5)


def test_dropout_switch_low_pass_filter():
    switch = DropoutSwitch(DropoutConfig(filter_gain=0.5, epsilon=0.002, stall_iterations=0))
    assert switch.update(1.0)  # no Delta I yet
    assert switch.update(0.8)  # Delta I 0.2, filtered 0.2
    assert switch.update(0.85)  # Delta I -0.05 is smoothed: 0.2 + 0.5 * (-0.25) = 0.075
    assert switch.filtered == pytest.approx(0.075)
    assert not switch.update(1.0)  # Delta I -0.15: 0.075 + 0.5 * (-0.225) < 0.002
    assert not switch.update(0.0)  # off for good
    unfiltered = DropoutSwitch(DropoutConfig(filter_gain=1.0, stall_iterations=0))
    unfiltered.update(1.0)
    unfiltered.update(0.8)
    assert not unfiltered.update(0.85)
    with pytest.raises(ConfigError, match="drop_factor"):
        DropoutConfig(drop_factor=1.0)
    with pytest.raises(ConfigError, match="epsilon"):
        DropoutConfig(epsilon=0.0)


# ---------------------------------------------------------------------------- scenarios
def test_two_disjoint_targets_alpha_cvt_beats_icvt_projection(two_targets, two_target_runs):
    _, acvt, icvt = two_target_runs
    print(f"\ntwo targets: alpha-CVT I = {acvt.metric[-1]:.3f} ({acvt.iterations} it, "
          f"{acvt.dropout_iterations} with dropout), iCVT+P I = {icvt.metric[-1]:.3f}")
    in_big, in_small = inside(BIG, acvt.final), inside(SMALL, acvt.final)
    assert np.all(in_big | in_small)
    assert (in_big.sum(), in_small.sum()) == (6, 4)
    assert acvt.converged and acvt.dropout_iterations > 0
    assert acvt.metric[-1] <= 0.10  # paper: 0.046
    # iCVT + projection gets every agent into a target but crowds the first one (paper 0.44)
    assert np.all(inside(BIG, icvt.final) | inside(SMALL, icvt.final))
    assert icvt.metric[-1] >= 0.3
    assert acvt.metric[-1] <= 0.25 * icvt.metric[-1]
    assert icvt.dropout_iterations == 0


def test_bullseye_alpha_cvt_beats_icvt_projection(bullseye_runs):
    _, acvt, icvt = bullseye_runs
    print(f"\nbullseye: alpha-CVT I = {acvt.metric[-1]:.3f} ({acvt.iterations} it), "
          f"iCVT+P I = {icvt.metric[-1]:.3f}")
    assert acvt.metric[-1] <= 0.15  # paper: 0.083
    assert acvt.metric[-1] <= 0.5 * icvt.metric[-1]  # paper: 0.367 for iCVT+P


def test_decentralized_two_targets_matches_centralized(two_targets, two_target_runs):
    starts, acvt, _ = two_target_runs
    run = run_offline(two_targets, "acvt", starts, config=OfflineConfig(max_iterations=150))
    final = run.positions[-1]
    value = final_deviation(two_targets, final)
    print(f"\ntwo targets: decentralized I = {value:.3f} ({run.iterations} it), "
          f"centralized {acvt.metric[-1]:.3f}")
    assert run.converged
    assert np.all(inside(BIG, final) | inside(SMALL, final))
    assert value <= 0.10
    assert value <= 2.0 * max(acvt.metric[-1], I_GRID_FLOOR)


@pytest.mark.slow
def test_decentralized_bullseye_within_twice_centralized(bullseye, bullseye_runs):
    starts, acvt, icvt = bullseye_runs
    run = run_offline(bullseye, "acvt", starts, config=OfflineConfig(max_iterations=150))
    value = final_deviation(bullseye, run.positions[-1])
    print(f"\nbullseye: decentralized I = {value:.3f} ({run.iterations} it), "
          f"centralized {acvt.metric[-1]:.3f}, iCVT+P {icvt.metric[-1]:.3f}")
    assert value <= 2.0 * acvt.metric[-1]
    assert value < icvt.metric[-1]


@pytest.mark.slow
def test_visibility_walls_reduce_uncovered_mass():
    """Paper Fig. 7 (two walls, 10 agents, I^L): a 10 m arena with two offset walls, agents
    starting in the lower-left corner behind the first wall."""
    occ = np.zeros((100, 100), np.int8)
    occ[34:36, 0:65] = OCCUPIED
    occ[64:66, 35:100] = OCCUPIED
    dom = arena(100, occ)
    starts = corner(10, origin=(0.6, 0.6), step=0.3, up=True)
    spec = CellSpec(visibility=True)
    acvt = AlphaCvt(dom, AcvtConfig(cells=spec)).run(starts)
    icvt = AlphaCvt(dom, AcvtConfig(cells=spec, dropout=DropoutConfig(enabled=False))).run(
        starts)
    print(f"\nwalls: alpha-CVT I^L = {acvt.metric[-1]:.3f}, iCVT+P I^L = {icvt.metric[-1]:.3f}")
    assert acvt.metric[-1] <= 0.2  # paper: 0.169
    assert acvt.metric[-1] < 0.6 * icvt.metric[-1]  # paper: 0.389
    assert (acvt.labels < 0).mean() < 0.01  # almost no target cell is unseen


def test_heterogeneous_agents_by_speed(two_targets):
    """Paper Fig. 14: five slow and five fast agents on the two targets (I^H, Eq. 18)."""
    speeds = np.r_[np.full(5, 0.4), np.full(5, 0.8)]  # [m/s], as in the paper's Fig. 18
    starts = corner(10)
    acvt = AlphaCvt(two_targets).run(starts, speeds)
    icvt = AlphaCvt(two_targets, AcvtConfig(dropout=DropoutConfig(enabled=False))).run(
        starts, speeds)
    print(f"\nheterogeneous: alpha-CVT I^H = {acvt.metric[-1]:.3f}, "
          f"iCVT+P I^H = {icvt.metric[-1]:.3f}")
    assert acvt.metric[-1] < 0.5 * icvt.metric[-1]
    fast, slow = acvt.masses[5:], acvt.masses[:5]
    assert fast.mean() > 2.0 * slow.mean()  # fast agents hold larger cells


# ---------------------------------------------------------------------------- strategy
def test_strategy_protocol_greedy_and_dropped_neighbours(two_targets):
    ctx = StrategyContext(domain=two_targets, robot_id=3)
    robot = make_strategy("acvt", ctx)
    first = robot.shared_state(Observation(3, np.array([5.0, 4.5, 0.0]), 0.0))
    assert first.mass is None and first.extra["reach"] == pytest.approx(ctx.robot.v_max)
    # Robot 3 alone in the small target, three neighbours in the big one, one of them with a
    # huge published mass. Masses 36 (own), 5, 40, 9: tau = 4/3 * 22.5 = 30.
    nbrs = [Neighbour(j, SharedState(np.array(p), mass=m, extra={"reach": ctx.robot.v_max}))
            for j, p, m in ((5, (11.0, 11.0), 5.0), (7, (18.0, 15.0), 40.0),
                            (9, (12.0, 15.0), 9.0))]
    d = robot.update(Observation(3, np.array([5.0, 4.5, 0.0]), 0.2), nbrs)
    assert d.mass == pytest.approx(36.0, rel=1e-6)
    assert d.details.greedy and d.shared.extra["greedy"] == 1.0
    assert d.details.dropped == (7,)
    assert d.shared.mass == d.mass and d.shared.extra["dropout"] == 1.0
    assert not d.converged
    assert inside(SMALL, d.goal[None])[0]
    with pytest.raises(ConfigError, match="unknown parameters"):
        make_strategy(strategy_choice("acvt", {"tau": 2.0}), ctx)
    with pytest.raises(ConfigError, match="filter_gain"):
        make_strategy(strategy_choice("acvt", {"filter_gain": 0.0}), ctx)
    with pytest.raises(ConfigError, match="stall_iterations"):
        make_strategy(strategy_choice("acvt", {"stall_iterations": 1.5}), ctx)
    assert make_strategy(strategy_choice("acvt", {"stall_iterations": 0}),
                         ctx).switch.config.stall_iterations == 0
    assert robot.switch.config.stall_iterations == STALL_ITERATIONS  # auto: separate targets
    assert DropoutConfig().stall_iterations == 0  # the centralized form: Alg. 2 as published
    with pytest.raises(ConfigError, match=r"acvt\.gap_penalty: must be a finite number"):
        make_strategy(strategy_choice("acvt", {"gap_penalty": "2"}), ctx)

