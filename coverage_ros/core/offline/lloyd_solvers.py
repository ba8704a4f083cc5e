"""Plain and accelerated Lloyd on a whole team's steps (:func:`solve_lloyd`).

The cost is the CVT energy ``H(P) = sum_i sum_{q in V_i} (|q - p_i|^2 - R_i^2) w(q) dA``, whose
gradient is ``dH/dp_i = 2 m_i (p_i - c_i)`` (Du, Faber & Gunzburger 1999): Lloyd's step to the
centroids is a gradient step preconditioned by ``1 / (2 m_i)``, and the fixed points are the
CVTs. A team (:class:`Team`) makes one tessellation per call; every call counts as one step.

* ``lloyd`` - plain Lloyd, the reference: every robot to its (projected) centroid.
* ``accelerated`` - plain Lloyd while the team spreads, then L-BFGS on H (Liu et al., "On
  centroidal Voronoi tessellation - energy smoothness and fast computation", 2009) with the
  Lloyd step as its preconditioner: the initial inverse Hessian is ``1 / (2 m_i)`` per robot, so
  with no curvature pairs the step is Lloyd's, and the residual ``goal - p`` (the projected
  centroid where the centroid is not a feasible place) stands for the negative preconditioned
  gradient. A step is kept only if every robot lands on a free cell and H drops by Armijo's
  sufficient decrease; else the plain Lloyd step is taken from there and the curvature pairs
  start again (a rejected try counts as a step).

  When to switch: H has many local minima (CVTs) a few tenths of a percent apart, and an early
  long step settles the team in another one than plain Lloyd would, as likely above it as below
  (up to 3 % above, switching from the start on random scenarios of 16-32 robots). So it
  switches once plain Lloyd's decrements look like a converging tail: their remaining sum,
  extrapolated as a geometric series (``d rho / (1 - rho)``, ``rho`` the larger of the last two
  ratios of decrements), is below ``settled`` of H. That extrapolation is a trigger, not a
  bound: plain Lloyd's decrements are irregular and it crosses plateaus (near saddles) that look
  converged (where random scenarios switched, plain Lloyd still had 0.07-8.5 % of H to go).
  What it buys is that the spreading, which picks the local minimum, is over; how often the end
  still differs from plain Lloyd's, and by how much, ``scripts/bench_planner`` measures on
  random scenarios (``docs/results/planner.json``).

  Then relocations (:data:`HOPS` at most), as the closet escape and the adaptive CVT's
  reinsertion move robots between cells: the robot of the cell that costs least goes into the
  cell that costs most, it and that cell's robot half the cell's radius either side of its
  goal, and the team descends again from there (plain Lloyd, then L-BFGS, as above). A try is
  kept if it ends lower by :data:`HOP_GAIN` of H, and the next starts from its end; the first
  that does not ends the tries. The end an early switch picked is as likely above plain
  Lloyd's as below; a relocation lowers it where a robot is worth more elsewhere, and costs a
  descent's steps where it is not.

The plain step is monotone, as the offline runner's robots are: the team moves to its goals if
H does not rise; else the robots whose cells' cost rose try half their steps (every robot, when
no cell's cost rose), and so on, a robot whose step falls below ``tolerance`` staying where it
is (each try counts as a step). A generalized Lloyd step on geodesic cells (a gradient step of
size ``1 / m_i``) can overshoot where a cell changes shape across a doorway, and the team would
swing there for good. A Euclidean Lloyd step to the centroids cannot raise H: only a goal
projected off an infeasible centroid can, so on such a team (``Team.overshoots`` false) the
second try keeps still exactly the robots whose projected goals are no nearer their centroids
than they are, which cannot raise H (one more tessellation, where halving took several; the
whole step comes first, as the cells made at the goals can gain more than such a robot loses,
and without it a robot held at an obstacle's side stayed there for good). The L-BFGS steps
leave those robots where they are (an active set, as in projected quasi-Newton methods).

Each descent stops when no robot's Lloyd step is longer than ``tolerance``, or when no step
that long lowers H.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from coverage_ros.errors import ConfigError

SOLVERS = ("lloyd", "accelerated")
#: Decrements the tail estimate looks at (:func:`remaining_decrease`).
TAIL_WINDOW = 3
#: The accelerated solver switches once plain Lloyd's extrapolated remaining decrease is below
#: this share of H (module docstring).
SETTLED = 2e-3
#: Relocations the accelerated solver tries after its descent, at most (module docstring).
HOPS = 3
#: A relocation is kept if its descent ends lower by this share of H (less: the same end).
HOP_GAIN = 1e-4
#: Armijo's sufficient decrease: the share of the linear prediction an L-BFGS step must reach.
ARMIJO = 1e-4
#: [relative] rounding allowed in a plain step's H before it counts as a rise
RISE = 1e-12


class Team(Protocol):
    """What the solvers need of a team: its domain (``is_free_point``), whether a step to its
    goals can overshoot (``overshoots``) and its steps, each with ``positions``, ``masses``,
    ``costs``, ``goals``, ``cost`` and ``step_length``."""

    domain: Any
    #: A step to the goals can raise a cell's cost by going too far (a gradient step: halve
    #: it); else only a goal moved off its centroid (projected to a feasible cell) can, and the
    #: robot stays.
    overshoots: bool

    def step(self, positions: np.ndarray, weights: np.ndarray | None = None) -> Any: ...


@dataclass
class LloydSolution:
    positions: np.ndarray  # (T + 1, n, 2) [m]: the accepted positions, start first
    energies: list[float]  # H of every tessellation made, in order
    steps: int  # tessellations made (each one team step's cost)
    converged: bool
    last: Any  # the team step at the final positions
    first: Any  # the team step at the start
    switched_at: int | None = None  # tessellations made when the acceleration began
    #: indices into ``positions`` where a relocation's descent begins (H rises there: one
    #: robot moved into another's cell)
    hops: list[int] = field(default_factory=list)

    @property
    def cost(self) -> float:
        return float(self.last.cost)

    def steps_within(self, H_target: float, share: float = 1e-3) -> int | None:
        """Tessellations made until one had H <= (1 + share) H_target (None: never)."""
        for k, h in enumerate(self.energies):
            if h <= (1.0 + share) * H_target:
                return k + 1
        return None


def remaining_decrease(energies: list[float], window: int = TAIL_WINDOW) -> float:
    """Plain Lloyd's remaining decrease of H estimated from its last ``window`` + 1 energies as a
    geometric tail with the largest ratio of successive decrements among them (inf while the
    decrements are not all positive and shrinking)."""
    if len(energies) < window + 1:
        return float("inf")
    d = -np.diff(energies[-window - 1:])
    if np.any(d <= 0):
        return float("inf")
    rho = float(np.max(d[1:] / d[:-1]))
    return float(d[-1] * rho / (1.0 - rho)) if rho < 1.0 else float("inf")


def solve_lloyd(team: Team, starts: np.ndarray, weights: np.ndarray | None = None,
                solver: str = "lloyd", tolerance: float = 0.02, max_steps: int = 1000,
                memory: int = 8, settled: float = SETTLED, tail_window: int = TAIL_WINDOW,
                hops: int = HOPS,
                progress: Callable[[int, float], None] | None = None) -> LloydSolution:
    """Lloyd from ``starts (n, 2)`` until no robot's step exceeds ``tolerance`` [m] or
    ``max_steps`` tessellations were made; the accelerated solver then tries at most ``hops``
    relocations (module docstring)."""
    if solver not in SOLVERS:
        raise ConfigError.at("solver", "unknown Lloyd solver", solver, f"one of {SOLVERS}")
    if max_steps < 1:
        raise ConfigError.at("max_steps", "must be >= 1", max_steps)
    if hops < 0:
        raise ConfigError.at("hops", "must be >= 0", hops)
    energies: list[float] = []

    def evaluate(X: np.ndarray) -> Any:
        s = team.step(X, weights)
        energies.append(s.cost)
        if progress is not None:
            progress(len(energies), s.cost)
        return s

    def descend(X: np.ndarray) -> _Descent:
        return _descend(team, evaluate(X), evaluate, solver, tolerance,
                        lambda: len(energies), max_steps, memory, settled, tail_window)

    start = np.asarray(starts, dtype=np.float64)[:, :2].copy()
    best = descend(start)
    first, path, hopped = best.first, list(best.path), []
    for _ in range(hops if solver == "accelerated" else 0):
        if len(energies) >= max_steps or not best.converged:
            break
        X = _relocated(best.last, team, weights)
        if X is None:
            break
        trial = descend(X)
        if not trial.last.cost < (1.0 - HOP_GAIN) * best.last.cost:
            break  # (a try that ends no lower: the landscape around holds no better end)
        hopped.append(len(path))
        path += trial.path
        best = _Descent(trial.path, trial.first, trial.last, trial.converged, best.switched_at)
    return LloydSolution(np.array(path), energies, len(energies), best.converged, best.last,
                         first, best.switched_at, hopped)


@dataclass
class _Descent:
    path: list[np.ndarray]  # (n, 2) [m] the accepted positions, the start first
    first: Any  # the team step at the start
    last: Any  # the team step where it stopped
    converged: bool
    switched_at: int | None


def _descend(team: Team, cur: Any, evaluate: Callable[[np.ndarray], Any], solver: str,
             tolerance: float, made: Callable[[], int], max_steps: int, memory: int,
             settled: float, tail_window: int) -> _Descent:
    """Plain or accelerated Lloyd from the team step ``cur`` until no robot's step exceeds
    ``tolerance``, no such step lowers H, or ``made()`` tessellations reach ``max_steps``."""

    def left() -> int:
        return max_steps - made()

    start, stalled = cur, False
    path = [cur.positions.copy()]
    plain = [cur.cost]  # energies of the plain steps before the switch
    switched_at = None
    pairs = _Curvature(memory)
    grad = _gradient(cur)
    while cur.step_length >= tolerance and left() > 0:
        nxt = None
        if solver == "accelerated" and switched_at is None and \
                remaining_decrease(plain, tail_window) < settled * cur.cost:
            switched_at = made()
        if switched_at is not None and pairs:
            x = cur.positions.ravel()
            d = pairs.direction(grad, cur.masses)
            if not team.overshoots:  # (robots the projection holds stay: an active set)
                d = (d.reshape(-1, 2) * _free_to_move(cur)[:, None]).ravel()
            slope = float(grad @ d)
            if slope < 0:
                cand = (x + d).reshape(-1, 2)
                if all(team.domain.is_free_point(q) for q in cand):
                    trial = evaluate(cand)
                    if trial.cost <= cur.cost + ARMIJO * slope:
                        nxt = trial
            if nxt is None:
                pairs.clear()  # start again from the plain step
        if nxt is None:
            if left() <= 0:
                break
            nxt = _monotone_step(cur, team, evaluate, tolerance, left())
            if nxt is None:  # (no step of at least the tolerance lowers H, or out of steps)
                stalled = left() > 0
                break
            if switched_at is None:
                plain.append(nxt.cost)
        new = _gradient(nxt)
        if solver == "accelerated":
            pairs.add(nxt.positions.ravel() - cur.positions.ravel(), new - grad)
        cur, grad = nxt, new
        path.append(cur.positions.copy())
    return _Descent(path, start, cur, bool(stalled or cur.step_length < tolerance), switched_at)


def _monotone_step(cur: Any, team: Team, evaluate: Callable[[np.ndarray], Any],
                   tolerance: float, budget: int) -> Any | None:
    """The team step at the goals of ``cur`` if its H is no higher than ``cur``'s; else, on a
    team that does not overshoot, the step of the robots :func:`_free_to_move` alone; else the
    steps of the robots whose cells' cost rose are halved (or, on a team that does not
    overshoot, dropped; every robot's halved when no cell's cost rose), a robot whose step
    falls below ``tolerance`` stays, and so on (module docstring). None when every robot
    stays, or ``budget`` tessellations raised H."""
    trial = evaluate(cur.goals)  # (the goals are free: the whole step needs no check)
    if trial.cost <= cur.cost * (1.0 + RISE) + RISE:
        return trial
    step = cur.goals - cur.positions
    length = np.hypot(step[:, 0], step[:, 1])
    budget -= 1
    if not team.overshoots and budget > 0:
        free = _free_to_move(cur) & (length > 0.0)
        X = cur.positions + free[:, None] * step
        if (free & (length >= tolerance)).any() and not free.all() and \
                all(team.domain.is_free_point(q) for q in X):
            settled = evaluate(X)
            budget -= 1
            if settled.cost <= cur.cost * (1.0 + RISE) + RISE:
                return settled
    share = np.ones(len(step))  # (else rounding: halve from the whole step's costs)
    while True:
        rose = (trial.costs > cur.costs) & (share > 0)
        if rose.any() and not team.overshoots:
            share[rose] = 0.0
        else:
            share[rose if rose.any() else share > 0] *= 0.5
        share[share * length < tolerance] = 0.0
        X = cur.positions + share[:, None] * step
        walled = np.array([not team.domain.is_free_point(q) for q in X])
        while walled.any():  # (part of the way across a wall: shorter still)
            share[walled] *= 0.5
            share[share * length < tolerance] = 0.0
            X = cur.positions + share[:, None] * step
            walled = np.array([not team.domain.is_free_point(q) for q in X])
        if not share.any() or budget == 0:
            return None
        trial = evaluate(X)
        budget -= 1
        if trial.cost <= cur.cost * (1.0 + RISE) + RISE:
            return trial


def _relocated(last: Any, team: Team, weights: np.ndarray | None) -> np.ndarray | None:
    """The positions of ``last`` with the robot of the cheapest cell moved into the costliest
    cell that takes it: that cell's robot and it at its goal -+ half its radius, across the
    line from the mover (None: no cell has room for both on free cells).

    A cell's radius here is that of a disc with its mean squared distance,
    ``sqrt(2 (cost / mass + R^2))``."""
    X: np.ndarray = np.array(last.positions, dtype=np.float64)
    R2 = np.zeros(len(X)) if weights is None else np.asarray(weights, dtype=np.float64) ** 2
    j = int(np.argmin(last.costs))
    for t in np.argsort(-last.costs, kind="stable"):
        if t == j or not last.masses[t] > 0:
            continue
        radius = math.sqrt(max(2.0 * (last.costs[t] / last.masses[t] + R2[t]), 0.0))
        c = last.goals[t]
        away = c - X[j]
        across = np.array([-away[1], away[0]]) / max(float(np.hypot(*away)), 1e-12)
        a, b = c + 0.5 * radius * across, c - 0.5 * radius * across
        if team.domain.is_free_point(a) and team.domain.is_free_point(b):
            X[j], X[t] = a, b
            return X
    return None


def _free_to_move(cur: Any) -> np.ndarray:
    """Robots whose goal is their centroid or a projection nearer it than they are (bool).

    On the cells of ``cur`` a robot's own term changes by ``m_i (|g_i - c_i|^2 - |p_i -
    c_i|^2)`` when it moves from p_i to g_i: no free robot raises it, so the step in which the
    free robots go and the others stay cannot raise H (the cells then made at the new
    positions are the best for them)."""
    c, g, p = cur.centroids, cur.goals, cur.positions
    free: np.ndarray = np.all(g == c, axis=1) | (np.hypot(*(g - c).T) < np.hypot(*(p - c).T))
    return free


def _gradient(step: Any) -> np.ndarray:
    """``2 m_i (p_i - goal_i)`` flattened: dH/dp where the centroid is the goal."""
    m = np.repeat(step.masses, 2)
    gradient: np.ndarray = 2.0 * m * (step.positions - step.goals).ravel()
    return gradient


class _Curvature:
    """The last ``memory`` L-BFGS pairs (position change, gradient change) and the two-loop
    recursion, with the Lloyd step ``1 / (2 m_i)`` as the initial inverse Hessian."""

    def __init__(self, memory: int) -> None:
        self.memory = memory
        self.s: list[np.ndarray] = []
        self.y: list[np.ndarray] = []

    def __bool__(self) -> bool:
        return bool(self.s)

    def clear(self) -> None:
        self.s.clear()
        self.y.clear()

    def add(self, s: np.ndarray, y: np.ndarray) -> None:
        sy = float(s @ y)
        if sy > 1e-12 * float(np.sqrt((s @ s) * (y @ y))):  # curvature: keeps H^-1 positive
            self.s.append(s)
            self.y.append(y)
            del self.s[:-self.memory], self.y[:-self.memory]

    def direction(self, grad: np.ndarray, masses: np.ndarray) -> np.ndarray:
        q = grad.copy()
        alphas = []
        for s, y in zip(reversed(self.s), reversed(self.y), strict=True):
            a = float(s @ q) / float(y @ s)
            alphas.append(a)
            q -= a * y
        r: np.ndarray = q / (2.0 * np.maximum(np.repeat(masses, 2), 1e-12))
        for (s, y), a in zip(zip(self.s, self.y, strict=True), reversed(alphas), strict=True):
            r += s * (a - float(y @ r) / float(y @ s))
        return -r
