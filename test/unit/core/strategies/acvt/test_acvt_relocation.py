"""Alpha-CVT's relocation (coverage_ros/core/strategies/acvt/relocation.py): a light agent of a
settled team is reinserted into a heavy cell when that is predicted to lower the metric - in
the centralized solver and in the decentralized strategy - and the paper's settings then end
balanced from every start cluster."""

from __future__ import annotations

import numpy as np
import pytest

from coverage_ros.bench.papers import lee2024_scenes as scenes
from coverage_ros.bench.papers.lee2024 import decentralized
from coverage_ros.core.geometry import points_in_polygon
from coverage_ros.core.strategies import (
    Neighbour,
    Observation,
    SharedState,
    StrategyContext,
    make_strategy,
    strategy_choice,
)
from coverage_ros.core.strategies.acvt.cells import CellSpec, MassCells
from coverage_ros.core.strategies.acvt.dropout import (
    STALL_ITERATIONS,
    AcvtConfig,
    AlphaCvt,
    DropoutConfig,
)
from coverage_ros.core.strategies.acvt.exchange import agent_regions, exchanges, swaps
from coverage_ros.core.strategies.acvt.plans import heard_plan, plan_extras
from coverage_ros.core.strategies.acvt.prediction import cvt_step, settle, team_metric
from coverage_ros.core.strategies.acvt.relocation import (
    DEFAULT_LEVEL_WINDOW,
    JUMP_DISTANCE,
    JUMP_HORIZON,
    JUMP_TOLERANCE,
    MetricLevel,
    RelocationConfig,
    best_relocation,
    insertion_point,
    movers,
)
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.errors import ConfigError

PAPER_FIG3_I = 0.046  # Lee & Lee, Fig. 3: alpha-CVT's I on two disjoint targets
PAPER_FIG14_IH = 0.0367  # Lee & Lee, Fig. 14: alpha-CVT's I^H, 5 + 5 agents at 0.4 / 0.8 m/s


def _in(poly: np.ndarray, pts: np.ndarray) -> int:
    return int(points_in_polygon(np.asarray(pts).reshape(-1, 2), poly).sum())


@pytest.fixture(scope="module")
def domain():
    return scenes.two_targets()


@pytest.fixture(scope="module")
def wrong_split(domain):
    """9 agents settled in BIG and 1 in SMALL - the paper's iCVT + projection result of Fig. 3
    (I = 0.44; the best split is 7 + 3): an equilibrium, which the paper's rule keeps once
    its dropout has ended."""
    rng = np.random.default_rng(3)
    starts = np.vstack([rng.uniform(BIG_LO, BIG_HI, (9, 2)), rng.uniform(SMALL_LO, SMALL_HI,
                                                                          (1, 2))])
    cells = MassCells(domain)
    return settle(cells, CellSpec(), starts, None, horizon=200, tolerance=1e-4)


BIG_LO, BIG_HI = scenes.BIG.min(axis=0) + 0.5, scenes.BIG.max(axis=0) - 0.5
SMALL_LO, SMALL_HI = scenes.SMALL.min(axis=0) + 0.5, scenes.SMALL.max(axis=0) - 0.5


def test_a_light_agent_goes_where_it_is_missing(domain, wrong_split):
    cells = MassCells(domain)
    labels, masses, before = team_metric(cells, CellSpec(), wrong_split, None)
    assert before == pytest.approx(0.44, abs=0.02)  # the paper's Fig. 3c value
    move = best_relocation(cells, CellSpec(), wrong_split, None, RelocationConfig())
    assert move is not None
    light = movers(masses, None, RelocationConfig().movers)
    assert len(move.agents) == 1  # one reach: no exchange or swap
    (agent,), (into,), point = move.agents, move.into, move.points[0]
    assert agent in light and _in(scenes.BIG, wrong_split[agent])
    assert _in(scenes.SMALL, point[None]) == 1  # into a cell of the small target
    assert move.metric_after < 0.3 < move.metric_before == pytest.approx(before)  # 8 + 2
    # The insertion point is the owner's mass cell farthest from it.
    own = labels == into
    far = np.hypot(*(cells.xy[own] - wrong_split[into]).T).max()
    assert np.hypot(*(point - wrong_split[into])) == pytest.approx(far)
    assert np.array_equal(move.point_of(agent), point) and move.point_of(99) is None
    assert insertion_point(cells, labels, wrong_split, 99) is None  # no cell, no point


def test_a_balanced_team_is_not_disturbed(domain, wrong_split):
    cells = MassCells(domain)
    P = wrong_split
    metrics = [team_metric(cells, CellSpec(), P, None)[2]]
    # 9 + 1 -> 8 + 2 -> 7 + 3, then a move within the big target to a more equal CVT; then
    # the team is left alone.
    while (move := best_relocation(cells, CellSpec(), P, None, RelocationConfig())):
        P = P.copy()
        P[list(move.agents)] = move.points
        P = settle(cells, CellSpec(), P, None, 200, 1e-4)
        metrics.append(team_metric(cells, CellSpec(), P, None)[2])
        assert len(metrics) <= 4 and metrics[-1] < metrics[-2]
        if len(metrics) == 3:
            assert (_in(scenes.BIG, P), _in(scenes.SMALL, P)) == (7, 3)
    assert (_in(scenes.BIG, P), _in(scenes.SMALL, P)) == (7, 3)
    assert metrics[-1] < 0.046 and len(metrics) >= 3


def test_the_centralized_run_relocates_only_when_settled_and_only_as_alpha_cvt(domain,
                                                                             wrong_split):
    # A threshold no agent reaches ends the dropout at once (Sec. II-C), so the paper's rule
    # then keeps the wrong split; the relocation mends it once the team has settled.
    silent = DropoutConfig(drop_factor=100.0)
    published = AlphaCvt(domain, AcvtConfig(dropout=silent,
                                            relocation=RelocationConfig(enabled=False)))
    kept = published.run(wrong_split)
    assert kept.relocations == 0 and kept.dropout_iterations == 0 and kept.metric[-1] > 0.4
    ours = AlphaCvt(domain, AcvtConfig(dropout=silent)).run(wrong_split)
    assert 2 <= ours.relocations <= 3 and ours.converged and ours.metric[-1] < 0.046
    assert np.allclose(ours.positions[0], kept.positions[0])  # the same run up to then
    assert (_in(scenes.BIG, ours.final), _in(scenes.SMALL, ours.final)) == (7, 3)
    baseline = AlphaCvt(domain, AcvtConfig(dropout=DropoutConfig(enabled=False)))
    assert baseline.run(wrong_split).relocations == 0  # iCVT + projection stays the paper's
    with pytest.raises(ConfigError, match=r"relocation\.margin"):
        RelocationConfig(margin=0.0)


MIXED = np.r_[np.full(5, scenes.SLOW), np.full(5, scenes.FAST)]


def _unequal_composition(cells: MassCells) -> np.ndarray:
    """Fig. 14's agents settled with four slow and one fast agent in the small target."""
    small = np.array([1, 1, 1, 1, 0, 1, 0, 0, 0, 0], dtype=bool)
    rng = np.random.default_rng(0)
    P = np.where(small[:, None], rng.uniform(SMALL_LO, SMALL_HI, (10, 2)),
                 rng.uniform(BIG_LO, BIG_HI, (10, 2)))
    return settle(cells, CellSpec(), P, MIXED, 200, 1e-4)


def test_an_exchange_mends_a_balanced_composition_whose_cells_stay_unequal(domain):
    """Fig. 14's setting: four slow agents and one fast one in the small target give it its
    share of R^2 (4 x 0.16 + 0.64 = 2 x 0.64, 32 % of the team's) but Lloyd's cells of mixed
    reach there stay unequal (I^H 0.066); every single move raises I^H. The exchange that
    sends the four slow agents to the large target and brings a second fast one (the other
    composition with the small target's share) is the one made - predicted with the swap that
    best follows it - and a swap of a slow and a fast agent in the large target then ends below
    the paper's value."""
    cells = MassCells(domain)
    R = MIXED
    small = np.array([1, 1, 1, 1, 0, 1, 0, 0, 0, 0], dtype=bool)
    P = _unequal_composition(cells)
    labels, masses, before = team_metric(cells, CellSpec(), P, R)
    assert before > 1.5 * PAPER_FIG14_IH
    assert agent_regions(cells, labels, 10).tolist() == small.astype(int).tolist()  # 0: BIG
    first = exchanges(cells, labels, masses, P, R, 4)[0]
    assert sorted(first.agents[:4]) == [0, 1, 2, 3] and R[first.agents[4]] == scenes.FAST
    assert _in(scenes.BIG, first.points[:4]) == 4 and _in(scenes.SMALL, first.points[4]) == 1
    # One agent at a time gets nowhere near the paper's value.
    single = best_relocation(cells, CellSpec(), P, R, RelocationConfig(exchanges=0))
    assert single is None or single.metric_after > 1.2 * PAPER_FIG14_IH
    move = best_relocation(cells, CellSpec(), P, R, RelocationConfig())
    assert move.agents == first.agents and move.metric_after < PAPER_FIG14_IH
    P[list(move.agents)] = move.points
    P = settle(cells, CellSpec(), P, R, 200, 1e-4)
    labels, masses, _ = team_metric(cells, CellSpec(), P, R)
    in_small = agent_regions(cells, labels, 10) == 1
    assert R[in_small].tolist() == [scenes.FAST, scenes.FAST]
    swap = best_relocation(cells, CellSpec(), P, R, RelocationConfig())
    i, j = swap.agents
    assert R[i] != R[j] and np.array_equal(swap.points, P[[j, i]])
    P[list(swap.agents)] = swap.points
    P = settle(cells, CellSpec(), P, R, 200, 1e-4)
    assert team_metric(cells, CellSpec(), P, R)[2] < PAPER_FIG14_IH
    # Swaps pair agents of different reach in one target; one reach has neither.
    regions = agent_regions(cells, *team_metric(cells, CellSpec(), P, R)[:1], 10)
    for e in swaps(cells, labels, masses, P, R, 12):
        a, b = e.agents
        assert R[a] != R[b] and regions[a] == regions[b]
    same = np.full(10, scenes.SLOW)
    assert exchanges(cells, labels, masses, P, same, 4) == []
    assert swaps(cells, labels, masses, P, same, 4) == []
    with pytest.raises(ConfigError, match=r"relocation\.exchanges"):
        RelocationConfig(exchanges=-1)


#: Where the decentralized team of Fig. 18a-c's setting (seed 1) stopped with the margin 0.002
#: and four plans: every Lloyd step 2 cm or less, I^H 0.097.
CRAWL = np.array([[14.93, 9.97], [13.24, 9.89], [13.8, 13.91], [12.12, 15.29], [16.58, 10.29],
                  [16.72, 12.79], [5.82, 3.68], [4.15, 5.35], [12.27, 12.32], [15.11, 15.64]])


def test_a_crawling_team_of_mixed_reaches_jumps_to_its_cvt(domain):
    """Lloyd's steps there are below a live robot's goal tolerance, but run on for a hundred
    steps they lead one agent 2.6 m to a CVT of I^H 0.018: a team of mixed reaches is sent
    there in one plan (the jump), and a move is weighed against that future, not against the
    crawl's present metric."""
    cells = MassCells(domain)
    P = CRAWL
    now = team_metric(cells, CellSpec(), P, MIXED)[2]
    step = np.hypot(*(cvt_step(cells, CellSpec(), P, MIXED) - P).T)
    assert now > 0.09 and step.max() < 0.025
    config = RelocationConfig()
    # At the predictions' tolerance (1 cm per step) the crawl would stop a step in.
    assert team_metric(cells, CellSpec(), settle(cells, CellSpec(), P, MIXED, JUMP_HORIZON,
                                                 config.tolerance), MIXED)[2] > 0.09
    future = settle(cells, CellSpec(), P, MIXED, JUMP_HORIZON,
                    JUMP_TOLERANCE * config.tolerance)
    far = np.flatnonzero(np.hypot(*(future - P).T) > JUMP_DISTANCE)
    assert len(far) >= 1 and team_metric(cells, CellSpec(), future, MIXED)[2] < 0.02
    move = best_relocation(cells, CellSpec(), P, MIXED, config)
    assert move.metric_before == pytest.approx(now) and move.metric_after < 0.02
    assert move.agents == tuple(far.tolist()) and np.allclose(move.points, future[far])
    # One reach: each robot moves on its own prediction, so no several-robot jump.
    same = best_relocation(cells, CellSpec(), P, None, RelocationConfig())
    assert same is None or len(same.agents) == 1


#: A live team of Fig. 18a-c's setting (seed 1) at 190 s: I^H 0.021.
LIVE_BALANCED = np.array([[13.47, 14.38], [14.26, 16.31], [11.36, 14.23], [12.49, 15.76],
                          [14.23, 9.62], [16.29, 14.61], [6.25, 4.56], [16.43, 11.39],
                          [3.75, 4.44], [12.57, 11.78]])


def test_a_balanced_team_of_mixed_reaches_is_left_alone(domain):
    """With the one-reach margin (0.002) the planner of that live team moved a robot for a
    predicted 0.0201 -> 0.0176, and the team stood at I^H 0.098 twenty seconds later; two
    more plans followed, the last still under way at the run's end (0.34). A team of mixed
    reaches needs the larger ``mixed_margin``."""
    cells = MassCells(domain)
    P = LIVE_BALANCED
    assert team_metric(cells, CellSpec(), P, MIXED)[2] < 0.022
    eager = best_relocation(cells, CellSpec(), P, MIXED,
                            RelocationConfig(mixed_margin=RelocationConfig().margin))
    assert eager is not None and eager.metric_after > 0.015
    assert best_relocation(cells, CellSpec(), P, MIXED, RelocationConfig()) is None
    assert RelocationConfig().margin_for(None) < RelocationConfig().margin_for(MIXED)
    with pytest.raises(ConfigError, match=r"relocation\.mixed_margin"):
        RelocationConfig(mixed_margin=-1.0)


def test_a_metric_has_levelled_off_once_it_stops_falling_by_the_margin():
    level = MetricLevel(3, 0.005)
    assert [level.record(v) for v in (0.20, 0.15, 0.12, 0.10, 0.09)] == [False] * 5
    # 0.10, 0.09, 0.088, 0.087: down by 0.013 over three updates - still falling
    assert not level.record(0.088) and not level.record(0.087)
    assert level.record(0.086)  # 0.09 -> 0.086 over the last three: levelled off
    assert level.record(0.087)  # a rise is no fall either
    level.reset()
    assert [level.record(0.05) for _ in range(4)] == [False, False, False, True]
    with pytest.raises(ConfigError, match="level_window"):
        MetricLevel(0, 0.005)


def test_a_mixed_team_moves_by_the_plan_its_lowest_id_robot_publishes(domain):
    """With mixed reaches only the robot of lowest id heard predicts; it publishes the exchange
    as a plan among its state's extras, and every robot the plan names drives to its point once
    (positions that differ by centimetres between robots cannot split the move)."""
    cells = MassCells(domain)
    P = _unequal_composition(cells)
    _, masses, _ = team_metric(cells, CellSpec(), P, MIXED)
    move = best_relocation(cells, CellSpec(), P, MIXED, RelocationConfig())
    assert len(move.agents) > 2

    def robot(rid):
        r = make_strategy("acvt", StrategyContext(domain=domain, robot_id=rid,
                                                  robot=RobotSpec(v_max=float(MIXED[rid]))))
        r.switch.stop()
        return r

    def state(i, extra=()):
        return SharedState(P[i].copy(), mass=masses[i],
                           extra={"reach": float(MIXED[i]), "dropout": 0.0, "greedy": 0.0,
                                  "settled": 1.0, "relocating": 0.0, **dict(extra)})

    def decide(r, rid, at, extra_of=()):
        nbrs = [Neighbour(i, state(i, extra_of if i == 0 else ())) for i in range(10)
                if i != rid]
        return r.update(Observation(rid, np.array([*at, 0.0]), 1.0), nbrs)

    other = next(a for a in move.agents if a != 0)
    assert decide(robot(other), other, P[other]).mode == "cvt"  # not the lowest id: waits
    lowest = robot(0)
    for _ in range(DEFAULT_LEVEL_WINDOW):  # it predicts once the team's metric has levelled
        waiting = decide(lowest, 0, P[0])
        assert "plan_from" not in waiting.shared.extra and not waiting.converged
    planner = decide(lowest, 0, P[0])
    extra = planner.shared.extra
    assert (extra["plan_from"], extra["plan_seq"]) == (0.0, 1.0)
    named = {a: pt for a, pt in zip(move.agents, move.points, strict=True)}
    for a, pt in named.items():
        assert (extra[f"plan_{a}_x"], extra[f"plan_{a}_y"]) == (pt[0], pt[1])
    assert planner.mode == ("relocate" if 0 in named else "cvt")
    assert not any(f"plan_{i}_x" in extra for i in range(10) if i not in named)
    follower = robot(other)
    first = decide(follower, other, P[other], extra)
    assert first.mode == "relocate" and np.allclose(first.goal, named[other])
    arrived = decide(follower, other, named[other], extra)  # at its point, the plan still heard
    assert arrived.mode != "relocate"  # a plan is carried out once
    assert heard_plan(5, [None, SharedState(P[0], extra=plan_extras(2, 3, {5: P[1]}))]) == \
        ((2, 3), pytest.approx(P[1]))
    assert heard_plan(5, [SharedState(P[0], extra=plan_extras(2, 3, {4: P[1]}))]) is None


def _state(p, mass, settled=1.0, dropout=0.0, relocating=0.0):
    return SharedState(np.asarray(p, float), mass=mass,
                       extra={"reach": 0.22, "dropout": dropout, "greedy": 0.0,
                              "settled": settled, "relocating": relocating})


def test_the_decentralized_robot_relocates_when_its_settled_team_lets_it(domain, wrong_split):
    cells = MassCells(domain)
    _, masses, _ = team_metric(cells, CellSpec(), wrong_split, None)
    (j,) = best_relocation(cells, CellSpec(), wrong_split, None, RelocationConfig()).agents
    light = movers(masses, None, RelocationConfig().movers)

    def decide(robot_id, **neighbour_state):
        """The robot's decision in the update after its team's metric has stayed level for
        DEFAULT_LEVEL_WINDOW updates (in which it waits, as in every update but the last)."""
        ctx = StrategyContext(domain=domain, robot_id=robot_id)
        robot = make_strategy("acvt", ctx)
        robot.switch.stop()  # its dropout phase is over
        nbrs = [Neighbour(i, _state(wrong_split[i], masses[i], **neighbour_state))
                for i in range(10) if i != robot_id]
        obs = Observation(robot_id, np.array([*wrong_split[robot_id], 0.0]), 1.0)
        for _ in range(DEFAULT_LEVEL_WINDOW):
            assert robot.update(obs, nbrs).mode == "cvt"
        return robot.update(obs, nbrs)

    d = decide(j)
    assert d.mode == "relocate" and not d.converged and _in(scenes.SMALL, d.goal) == 1
    assert d.details.predicted < 0.3 and d.shared.extra["relocating"] == 1.0
    # The other light robots predict the same relocation, which is not theirs; a heavy robot
    # does not predict at all.
    for other in [i for i in light if i != j] + [int(np.argmax(masses))]:
        assert decide(other).mode == "cvt"
    assert decide(j, settled=0.0).mode == "cvt"  # a neighbour still moving: waits
    assert decide(j, dropout=1.0).mode == "cvt"  # a neighbour still in its dropout: waits
    params = strategy_choice("acvt", {"relocate": False})
    robot = make_strategy(params, StrategyContext(domain=domain, robot_id=j))
    robot.switch.stop()
    nbrs = [Neighbour(i, _state(wrong_split[i], masses[i])) for i in range(10) if i != j]
    assert robot.update(Observation(j, np.array([*wrong_split[j], 0.0]), 1.0),
                        nbrs).mode == "cvt"


@pytest.mark.slow
def test_the_decentralized_strategy_ends_balanced_from_several_starts():
    """The same for the robots' own updates (coverage-plan --strategy acvt) on our disc and
    rectangle, from two starts where the published rule ends with 5 + 5 instead of 4 + 6."""
    domain = scenes.own_shape("disc and rectangle")
    starts = [scenes.corner_cluster(s, 10) for s in (1, 5)]
    ours = [decentralized(domain, p) for p in starts]
    published = decentralized(domain, starts[0], relocate=False)
    print(f"\ndecentralized I: {np.round(ours, 3).tolist()}, published rule {published:.3f}")
    assert max(ours) <= 2 * PAPER_FIG3_I
    assert published > 0.15


def test_relocate_auto_is_on_for_separate_targets_only(domain):
    """The default ``relocate: auto`` relocates where the density's support has separate
    parts (Lee & Lee's targets) and not on one connected area (a room, a building map: there a
    relocation only trades the coverage cost H for mass balance)."""
    room = scenes.two_walls()
    assert MassCells(domain).regions == 2 and MassCells(room).regions == 1
    assert MassCells(scenes.crop_field()).regions > 2
    for dom, on in ((domain, True), (room, False)):
        robot = make_strategy("acvt", StrategyContext(domain=dom, robot_id=0))
        assert robot.relocation.enabled is on
        # stall_iterations: auto likewise (in the live room it ended the dropout too early)
        assert robot.switch.config.stall_iterations == (STALL_ITERATIONS if on else 0)
    fixed = make_strategy(strategy_choice("acvt", {"stall_iterations": 7}),
                          StrategyContext(domain=room, robot_id=0))
    assert fixed.switch.config.stall_iterations == 7
    forced = make_strategy(strategy_choice("acvt", {"relocate": True}),
                           StrategyContext(domain=room, robot_id=0))
    assert forced.relocation.enabled
    auto = make_strategy(strategy_choice("acvt", {"relocate": "auto"}),
                         StrategyContext(domain=domain, robot_id=0))
    assert auto.relocation.enabled
    for wrong in ("sometimes", 1):
        with pytest.raises(ConfigError, match="relocate"):
            strategy_choice("acvt", {"relocate": wrong})


def test_a_team_whose_plans_are_spent_is_sent_back_to_the_best_cvt_its_planner_foresaw(domain):
    """Fig. 14's agents. The planner (robot 0) has made its plans; it predicted from a good
    composition (two fast agents in the small target) and records the CVT that team reaches
    on its own. When the team then settles in a worse one (four slow agents and a fast one in
    the small target), its last plan sends every robot that is not there back to its place in
    the best CVT foreseen; then it plans no more."""
    from coverage_ros.core.strategies.acvt.relocation import own_future
    from coverage_ros.core.strategies.acvt.strategy import MAX_PLANS

    cells = MassCells(domain)
    rng = np.random.default_rng(1)
    small = np.array([0, 0, 0, 0, 0, 1, 1, 0, 0, 0], dtype=bool)
    good = settle(cells, CellSpec(), np.where(small[:, None],
                                              rng.uniform(SMALL_LO, SMALL_HI, (10, 2)),
                                              rng.uniform(BIG_LO, BIG_HI, (10, 2))),
                  MIXED, 200, 1e-4)
    bad = _unequal_composition(cells)
    config = RelocationConfig()
    best_places, best = own_future(cells, CellSpec(), good, MIXED, config)
    assert best < team_metric(cells, CellSpec(), bad, MIXED)[2] - 0.01
    planner = make_strategy("acvt", StrategyContext(domain=domain, robot_id=0,
                                                    robot=RobotSpec(v_max=float(MIXED[0]))))
    planner.switch.stop()
    planner._plans = MAX_PLANS

    def settled_at(P):
        _, masses, _ = team_metric(cells, CellSpec(), P, MIXED)
        nbrs = [Neighbour(i, SharedState(P[i].copy(), mass=masses[i], extra={
            "reach": float(MIXED[i]), "dropout": 0.0, "greedy": 0.0, "settled": 1.0,
            "relocating": 0.0})) for i in range(1, 10)]
        return [planner.update(Observation(0, np.array([*P[0], 0.0]), 1.0), nbrs)
                for _ in range(DEFAULT_LEVEL_WINDOW + 1)][-1]

    assert "plan_from" not in settled_at(good).shared.extra  # (at its best: no way back)
    back = settled_at(bad)
    extra = back.shared.extra
    assert (extra["plan_from"], extra["plan_seq"]) == (0.0, MAX_PLANS + 1.0)
    far = np.hypot(*(best_places - bad).T) > planner.context.convergence_tolerance
    assert far.sum() >= 2
    for i in range(10):
        if far[i]:
            assert (extra[f"plan_{i}_x"], extra[f"plan_{i}_y"]) == tuple(best_places[i])
        else:
            assert f"plan_{i}_x" not in extra
    assert back.details.predicted == pytest.approx(best)
    # Another settled team, the planner at its place: no plan after the way back.
    later = bad + 0.05
    later[0] = best_places[0]
    after = settled_at(later)
    assert after.shared.extra.get("plan_seq") == MAX_PLANS + 1.0 and after.mode != "relocate"
