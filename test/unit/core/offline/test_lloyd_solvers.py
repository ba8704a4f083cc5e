"""Plain and accelerated Lloyd (coverage_ros.core.offline.lloyd_solvers): where they end, that H
never rises, that the safeguard throws out steps that raise H, and that where they stop is a
centroidal Voronoi configuration."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.offline.lloyd_solvers import _relocated, remaining_decrease, solve_lloyd
from coverage_ros.core.offline.lloyd_team import EuclideanTeam
from coverage_ros.core.world.density import GaussianMixture, UniformDensity
from coverage_ros.core.world.grid import OCCUPIED, GridMap
from coverage_ros.errors import ConfigError

TOL = 1e-4  # [m]


def _domain(kind: str) -> CoverageDomain:
    """An 8 m square at 5 cm: two Gaussians, uniform, or two boxes and one Gaussian."""
    occ = np.zeros((160, 160), dtype=np.int8)
    density = GaussianMixture(np.array([[2.0, 5.5], [6.0, 2.5]]),
                              np.array([np.diag([1.2, 0.8]) ** 2, np.eye(2) * 1.5 ** 2]),
                              np.array([1.0, 0.7]))
    if kind == "uniform":
        density = UniformDensity()
    if kind == "obstacles":
        occ[60:100, 50:70] = OCCUPIED
        occ[20:35, 100:140] = OCCUPIED
        density = GaussianMixture(np.array([[5.0, 5.0]]), np.array([np.eye(2) * 2.0 ** 2]),
                                  np.array([1.0]))
    return CoverageDomain.from_grid(GridMap(occ, 0.05, (0.0, 0.0, 0.0)), 0.105, density)


def _corner(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return 0.5 + rng.uniform(0.0, 1.5, (n, 2))


@pytest.fixture(scope="module", params=[("gaussians", 6), ("uniform", 7), ("obstacles", 6)])
def runs(request):
    kind, n = request.param
    team = EuclideanTeam(_domain(kind))
    starts = _corner(n, n)
    out = {s: solve_lloyd(team, starts, solver=s, tolerance=TOL, max_steps=2000)
           for s in ("lloyd", "accelerated")}
    out["team"] = team
    return out


def test_accelerated_ends_within_a_tenth_of_a_percent_of_plain(runs):
    plain, fast = runs["lloyd"], runs["accelerated"]
    assert plain.converged and fast.converged
    assert fast.cost <= 1.001 * plain.cost
    assert fast.switched_at is not None and fast.switched_at < fast.steps
    assert fast.steps_within(plain.cost) is not None


def test_energy_of_accepted_positions_never_rises_within_a_descent(runs):
    """H never rises along a descent; a relocation starts a new one (H rises there), kept only
    if it ends lower than the descent before."""
    team = runs["team"]
    assert runs["lloyd"].hops == []
    for solver in ("lloyd", "accelerated"):
        sol = runs[solver]
        E = np.array([team.step(P).cost for P in sol.positions])
        bounds = [0, *sol.hops, len(E)]
        ends = []
        for a, b in itertools.pairwise(bounds):
            assert np.all(np.diff(E[a:b]) <= 1e-9 * E[a:b - 1]), solver
            ends.append(E[b - 1])
        assert np.all(np.diff(ends) < 0), solver
        for h in sol.hops:
            assert E[h] > E[h - 1]  # (one robot moved into another's cell)
    fast = runs["accelerated"]
    assert len(fast.positions) <= fast.steps == len(fast.energies)


def test_a_fixed_point_is_a_centroidal_voronoi_configuration(runs):
    """Where a solver stops, every robot is at the mass centroid of its own cell, with the cells
    labelled cell by cell (the reference step), to the tolerance; and the gradient
    2 m_i (p_i - c_i) vanishes to that order."""
    team = runs["team"]
    for solver in ("lloyd", "accelerated"):
        P = runs[solver].positions[-1]
        ref = team.reference_step(P)
        off = np.hypot(*(ref.centroids - P).T)
        assert off.max() < TOL, solver
        assert all(team.domain.is_free_point(p) for p in P)
        assert np.abs(2 * ref.masses * off).max() < 2 * TOL * ref.masses.max()


class _Penalized:
    """A team whose H is raised by 1 wherever the positions are not the Lloyd goals of the step
    before: every extrapolation looks worse, and the safeguard must refuse it."""

    overshoots = False

    def __init__(self, team: EuclideanTeam) -> None:
        self.domain = team.domain
        self._team = team
        self._goals: list[np.ndarray] = []

    def step(self, positions, weights=None):
        s = self._team.step(positions, weights)
        lloyd = any(np.array_equal(positions, g) for g in self._goals) or not self._goals
        self._goals.append(s.goals)
        if lloyd:
            return s
        return type(s)(s.positions, s.masses, s.costs + 1.0 / len(s.costs), s.centroids,
                       s.goals, s.cells, s.geodesic)


def test_safeguard_refuses_steps_that_raise_the_energy():
    team = EuclideanTeam(_domain("gaussians"))
    starts = _corner(6, 6)
    plain = solve_lloyd(team, starts, solver="lloyd", tolerance=TOL, max_steps=2000)
    fast = solve_lloyd(_Penalized(team), starts, solver="accelerated", tolerance=TOL,
                       max_steps=4000)
    # every accepted step was Lloyd's: the same path as plain Lloyd, the tries counted on top
    assert np.array_equal(fast.positions, plain.positions)
    assert fast.steps > plain.steps
    assert fast.cost == pytest.approx(plain.cost, rel=1e-12)


def test_remaining_decrease_of_a_geometric_tail():
    H = [10.0 + 3.0 * 0.9 ** k for k in range(12)]
    assert remaining_decrease(H) == pytest.approx(3.0 * 0.9 ** 11, rel=1e-9)
    assert remaining_decrease(H[:3]) == float("inf")
    assert remaining_decrease([5.0, 4.0, 4.0, 3.0]) == float("inf")  # a stall: not a tail
    assert remaining_decrease([5.0, 4.5, 3.0, 1.0]) == float("inf")  # growing decrements


def test_a_euclidean_step_that_raises_h_is_followed_by_one_that_cannot():
    """On a Euclidean team only a projected goal can raise H: after a whole step that does, the
    step in which the robots whose projected goals are no nearer their centroids stay is
    accepted at once - at most one tessellation thrown away per accepted step."""
    team = EuclideanTeam(_domain("obstacles"))
    made = team.step
    costs: list[float] = []

    def step(positions, weights=None):
        s = made(positions, weights)
        costs.append(s.cost)
        return s

    team.step = step  # type: ignore[method-assign]
    rejected = 0
    for n, seed in ((12, 7), (16, 7), (16, 10)):  # (starts whose runs need the rule)
        costs.clear()
        r = solve_lloyd(team, _corner(n, seed), solver="lloyd", tolerance=TOL, max_steps=2000)
        assert r.converged
        accepted, runs = costs[0], [0]
        for c in costs[1:]:
            if c <= accepted * (1.0 + 1e-12) + 1e-12:
                accepted = c
                runs.append(0)
            else:
                runs[-1] += 1
        assert max(runs[:-1]) <= 1, (n, seed)  # (the last: the tries before the stop)
        rejected += sum(runs[:-1])
    assert rejected >= 5  # (the rule was needed)


def test_a_relocation_lowers_the_end_an_early_switch_picked():
    """Seven robots on a uniform square: the descent alone ends in a CVT 1 % above the one a
    robot moved from the cheapest cell into the costliest reaches; plain Lloyd tries none."""
    team = EuclideanTeam(_domain("uniform"))
    starts = _corner(7, 7)
    alone = solve_lloyd(team, starts, solver="accelerated", tolerance=TOL, max_steps=2000,
                        hops=0)
    hopped = solve_lloyd(team, starts, solver="accelerated", tolerance=TOL, max_steps=2000)
    assert alone.hops == [] and len(hopped.hops) >= 1
    assert hopped.cost < 0.995 * alone.cost
    assert hopped.converged
    # the path up to the first relocation is the descent alone
    h = hopped.hops[0]
    assert np.array_equal(hopped.positions[:h], alone.positions)
    moved = np.flatnonzero(np.any(hopped.positions[h] != alone.positions[-1], axis=1))
    assert len(moved) == 2  # the mover and the robot of the cell it went into
    assert solve_lloyd(team, starts, solver="lloyd", tolerance=TOL, max_steps=2000).hops == []


def test_relocation_moves_the_cheapest_cells_robot_into_the_costliest_cell():
    team = EuclideanTeam(_domain("uniform"))
    P = np.array([[1.0, 1.0], [1.6, 1.2], [5.0, 5.0], [2.0, 6.5]])
    step = team.step(P)
    j, t = int(np.argmin(step.costs)), int(np.argmax(step.costs))
    X = _relocated(step, team, None)
    assert X is not None
    assert np.array_equal(np.delete(X, [j, t], axis=0), np.delete(P, [j, t], axis=0))
    radius = np.sqrt(2.0 * step.costs[t] / step.masses[t])
    for k in (j, t):
        assert np.hypot(*(X[k] - step.goals[t])) == pytest.approx(radius / 2)
    assert np.hypot(*(X[j] - X[t])) == pytest.approx(radius)
    # across the line from where the mover stood
    assert abs(np.dot(X[j] - X[t], step.goals[t] - P[j])) < 1e-9
    # a power weight widens the cell's radius: sqrt(2 (cost / mass + R^2))
    R = np.array([0.0, 0.0, 0.3, 0.0])
    weighted = team.step(P, R)
    t = int(np.argmax(weighted.costs))
    Xw = _relocated(weighted, team, R)
    assert Xw is not None
    wide = np.sqrt(2.0 * (weighted.costs[t] / weighted.masses[t] + R[t] ** 2))
    assert np.hypot(*(Xw[t] - weighted.goals[t])) == pytest.approx(wide / 2)


def test_no_relocation_where_no_cell_has_room_and_bad_counts_are_refused():
    team = EuclideanTeam(_domain("uniform"))
    step = team.step(_corner(4, 1))

    class Walled:
        overshoots = False

        class domain:  # noqa: N801 (stands in for a domain with every point blocked)
            @staticmethod
            def is_free_point(p):
                return False

    assert _relocated(step, Walled(), None) is None
    with pytest.raises(ConfigError, match="hops"):
        solve_lloyd(team, _corner(4, 1), solver="accelerated", hops=-1)
