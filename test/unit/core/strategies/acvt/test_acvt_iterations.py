"""The decentralized alpha-CVT tests Delta I once per iteration of Alg. 2, also on robots that
move a little per update (:mod:`coverage_ros.core.strategies.acvt.iterations`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies import make_strategy, strategy_choice
from coverage_ros.core.strategies.acvt.cells import CellSpec, MassCells
from coverage_ros.core.strategies.acvt.iterations import (
    MoveIterations,
    awaiting_mass,
    peer_counts,
)
from coverage_ros.core.strategies.acvt.prediction import team_metric
from coverage_ros.core.strategies.base import (
    Neighbour,
    Observation,
    SharedState,
    StrategyContext,
)
from coverage_ros.core.world.density import UniformDensity
from coverage_ros.core.world.grid import OCCUPIED, GridMap
from coverage_ros.core.world.robot import RobotSpec


def test_an_iteration_ends_when_the_move_is_done_and_the_neighbours_have_caught_up():
    it = MoveIterations(speed=0.8, arrive=0.15)
    assert it.due(np.zeros(2), 0.0, [])  # the first sample: nothing to wait for
    it.sampled(np.zeros(2), np.array([4.0, 0.0]), 0.0)
    assert it.count == 1
    # 4 m at 0.8 m/s: 5 s at best; allowed 2 * 5 + 1 = 11 s.
    assert not it.due(np.array([0.4, 0.0]), 0.5, [1.0])
    assert not it.due(np.array([3.0, 0.0]), 10.9, [5.0])
    assert it.due(np.array([3.9, 0.0]), 5.2, [1.0, 2.0])  # arrived
    assert not it.due(np.array([3.9, 0.0]), 5.2, [1.0, 0.0])  # a neighbour is behind
    assert it.due(np.array([1.0, 0.0]), 11.0, [])  # out of time: done where it is
    assert it.due(np.array([1.0, 0.0]), -3.0, [])  # the clock jumped back (a restart)
    # A robot that jumps to its goal is done at the next update.
    it.sampled(np.array([3.9, 0.0]), np.array([6.0, 1.0]), 5.2)
    assert it.due(np.array([6.0, 1.0]), 5.4, [2.0, 3.0])


def test_a_neighbour_out_of_step_is_not_waited_for():
    """The barrier keeps neighbours within one iteration; one that is two or more behind joined
    late, restarted, or comes from a part of the team that was out of range."""
    it = MoveIterations(speed=0.8, arrive=0.15)
    for t in range(5):
        it.sampled(np.zeros(2), np.zeros(2), float(t))
    assert it.count == 5
    assert not it.due(np.zeros(2), 6.0, [5.0, 4.0])  # one behind: still moving
    assert it.due(np.zeros(2), 6.0, [5.0, 3.0])
    assert it.due(np.zeros(2), 6.0, [0.0, 9.0])  # restarted; ahead


def test_a_robot_behind_its_neighbours_takes_up_their_count():
    it = MoveIterations(speed=0.8, arrive=0.15)
    it.sampled(np.zeros(2), np.zeros(2), 0.0, [7.0, 12.0])
    assert it.count == 12
    it.sampled(np.zeros(2), np.zeros(2), 1.0, [12.0, 13.0])
    assert it.count == 13  # in step: one more, as without peers
    it.sampled(np.zeros(2), np.zeros(2), 2.0)
    assert it.count == 14


def test_changing_neighbourhoods_keep_the_counts_in_step_and_nobody_waits_for_a_late_joiner():
    """Robots on a line, neighbours within two places (``comm_range``), each sampling once per
    round when its barrier lets it (its move is done at once, as offline). Robot 5 starts 30
    rounds late, out of range, and then appears in the middle of the line."""
    n, late = 6, 30
    its = [MoveIterations(speed=1.0, arrive=0.1) for _ in range(n)]
    places = [0.0, 1.0, 2.0, 3.0, 4.0, 100.0]
    published = [0] * n  # counts as heard (one round old)
    stalled = 0
    for t in range(60):
        if t == late:
            places[5] = 2.5
        awake = [i for i in range(n) if i < 5 or t >= late]
        before = [it.count for it in its]
        for i in awake:
            peers = [float(published[j]) for j in awake
                     if j != i and abs(places[j] - places[i]) <= 2]
            if its[i].due(np.zeros(2), float(t), peers):
                its[i].sampled(np.zeros(2), np.zeros(2), float(t), peers)
        if t >= late and all(its[i].count == before[i] for i in range(5)):
            stalled += 1
        published = [it.count for it in its]
        for i in awake:  # neighbours in range stay within one iteration of each other
            for j in awake:
                if abs(places[j] - places[i]) <= 2 and (t < late or t > late):
                    assert abs(its[i].count - its[j].count) <= 1, (t, i, j)
    assert stalled == 0  # the team kept sampling when robot 5 appeared ...
    assert its[5].count >= 59  # ... and robot 5 was in step at its first sample
    assert max(it.count for it in its) - min(it.count for it in its) <= 1


def test_only_neighbours_still_in_their_dropout_are_waited_for():
    states = [SharedState(np.zeros(2), extra={"dropout": 1.0, "iteration": 4.0}),
              SharedState(np.zeros(2), extra={"dropout": 0.0, "iteration": 1.0}),
              SharedState(np.zeros(2), extra={"dropout": 1.0}),
              SharedState(np.zeros(2), extra={})]
    assert peer_counts(states) == [4.0]


def test_the_dropout_is_not_tested_before_every_acvt_neighbour_has_published_a_mass(room):
    """Live robots make their first updates a few tenths of a second apart: a robot that tested
    the masses of the first two up (M and M / 2: nobody reaches tau_drop = 2 mean M) ended its
    dropout for good. A neighbour's first state carries the strategy's extras but no mass."""
    ctx = StrategyContext(domain=room, robot_id=0)
    here = np.array([1.0, 1.0, 0.0])
    first = make_strategy("acvt", StrategyContext(domain=room, robot_id=2)).shared_state(
        Observation(2, np.array([2.0, 1.2, 0.0]), 0.0))
    assert first.mass is None and first.extra["dropout"] == 1.0
    assert first.extra["iteration"] == 0.0

    def team(mass_1: float, mass_2: float | None) -> list[Neighbour]:
        extra = {**first.extra}
        return [Neighbour(1, SharedState(np.array([1.5, 1.0]), mass=mass_1, extra=extra)),
                Neighbour(2, SharedState(np.array([2.0, 1.2]), mass=mass_2, extra=extra))]

    # Its own mass here (a robot that hears nobody's mass makes no test).
    probe = make_strategy("acvt", ctx).update(Observation(0, here, 0.5), team(math.nan, None))
    own = probe.mass
    robot = make_strategy("acvt", ctx)
    d = robot.update(Observation(0, here, 0.5), team(0.5 * own, None))
    assert awaiting_mass([n.state for n in team(0.5 * own, None)])
    assert d.details.dropout and robot.iterations.count == 0  # waits for robot 2's mass
    # M, M / 2, M / 10: tau_drop = 1.5 * 0.53 M = 0.8 M, this robot is greedy.
    d = robot.update(Observation(0, here, 1.0), team(0.5 * own, 0.1 * own))
    assert d.details.dropout and d.details.greedy and robot.iterations.count == 1
    # Without robot 2 (another strategy, or not there) the same two masses end it at once.
    alone = make_strategy("acvt", ctx)
    d = alone.update(Observation(0, here, 0.5), team(0.5 * own, None)[:1])
    assert not d.details.dropout


def test_a_robot_announces_its_dropout_before_its_first_update(room):
    from coverage_ros.core.control.controller import ControllerConfig, RobotController

    controller = RobotController(room, ControllerConfig(robot_id=3,
                                                        strategy=strategy_choice("acvt")))
    controller.set_pose((1.0, 1.0, 0.0))
    state = controller.presence_state()
    assert state["dropout"] == 1.0 and state["iteration"] == 0.0
    assert state["x"] == 1.0 and "mass" not in state


ROOM = 10.0  # [m] the paper's Fig. 7 room, two offset walls (as in the live Figs. 17d-f)


@pytest.fixture(scope="module")
def room() -> CoverageDomain:
    occ = np.zeros((100, 100), np.int8)
    occ[34:36, 0:65] = OCCUPIED
    occ[64:66, 35:100] = OCCUPIED
    return CoverageDomain.from_grid(GridMap(occ, 0.1), 0.105, UniformDensity())


def _gradual_team(domain: CoverageDomain, starts: np.ndarray, speed: float, period: float,
                  duration: float, params: dict) -> tuple[np.ndarray, list]:
    """Robots that update every ``period`` [s] and then drive at most ``speed * period``
    along a shortest path towards their goals (not onto each other), hearing each other's
    states one update old - the pace of a live team, without its physics."""
    from scipy.sparse.csgraph import dijkstra

    n = len(starts)
    spec = RobotSpec(v_max=speed)
    robots = [make_strategy(strategy_choice("acvt", params),
                            StrategyContext(domain=domain, robot=spec, robot_id=i))
              for i in range(n)]
    pos = np.asarray(starts, float).copy()
    shared = [r.shared_state(Observation(i, np.r_[pos[i], 0.0], 0.0))
              for i, r in enumerate(robots)]
    W = domain.shape[1]

    def node(p: np.ndarray) -> int:
        g = domain.to_grid(p)[0].astype(int)
        return int(g[1] * W + g[0])

    ends = []
    for step in range(1, int(duration / period) + 1):
        decisions = [r.update(Observation(i, np.r_[pos[i], 0.0], step * period),
                              [Neighbour(j, shared[j]) for j in range(n) if j != i])
                     for i, r in enumerate(robots)]
        shared = [d.shared for d in decisions]
        ends.append([d.details.dropout for d in decisions])
        for i, d in enumerate(decisions):
            a, b = node(pos[i]), node(d.goal)
            if a == b:
                pos[i] = d.goal
                continue
            _, pred = dijkstra(domain.graph.csr, directed=True, indices=a,
                               return_predecessors=True)
            path = [b]
            while path[-1] != a and pred[path[-1]] >= 0:
                path.append(int(pred[path[-1]]))
            pts = domain.to_map(domain.node_centers(np.array(path[::-1])))
            pts[-1] = d.goal
            budget, p = speed * period, pos[i].copy()
            for q in pts[1:]:
                length = float(np.hypot(*(q - p)))
                if length > budget:
                    p = p + (q - p) * budget / length
                    break
                p, budget = q, budget - length
            # Bodies do not pass through each other: a move that ends on another robot (or
            # closer to it than before, when already touching) is not made.
            others = np.delete(pos, i, axis=0)
            gap_now = np.hypot(*(others - pos[i]).T)
            gap_new = np.hypot(*(others - p).T)
            if np.all((gap_new >= 2 * spec.radius) | (gap_new > gap_now)):
                pos[i] = p
    return pos, ends


@pytest.mark.slow
def test_a_team_moving_at_live_pace_keeps_its_dropout_until_the_split_is_right(room):
    """The live Lee room (Figs. 17d-f, 0.8 m/s, updates every 0.5 s): fed per update, every
    robot's dropout ended 13 s into the run with the team split 6 + 2 + 2 between the three
    corridors (I^L 0.50); fed per iteration it runs until the split is 4 + 3 + 3 or so, and
    I^L ends near the offline run's (0.13 from these starts) and the paper's 0.187."""
    starts = np.array([[2.203, 1.311], [1.615, 1.439], [2.535, 1.732], [1.531, 0.626],
                       [0.720, 1.149], [1.260, 0.893], [1.611, 1.100], [2.089, 1.780],
                       [1.819, 1.942], [1.253, 2.016]])
    final, dropout = _gradual_team(room, starts, 0.8, 0.5, 150.0, {"visibility": True})
    on = np.array(dropout).any(axis=1)
    lasted = 0.5 * (np.flatnonzero(on)[-1] + 1)
    metric = team_metric(MassCells(room), CellSpec(visibility=True), final, None)[2]
    corridors = np.histogram(final[:, 1], bins=[0.0, 3.5, 6.5, ROOM])[0]
    print(f"\nlive pace: dropout for {lasted:.1f} s, corridors {corridors.tolist()}, "
          f"I^L {metric:.3f}")
    assert lasted > 40.0
    assert corridors.min() >= 3
    assert metric <= 0.25
