"""Lloyd on virtual generators, TangentBug to the real targets (Breitenmoser et al. 2010).

Breitenmoser, Schwager, Metzger, Siegwart, Rus, "Voronoi coverage of non-convex environments
with a group of networked robots" (ICRA 2010), Algorithms 1 and 2:

* Level 1 (Lloyd, Alg. 1): each robot keeps a *virtual generator* ``g_virt`` that moves as if the
  world were convex (straight through obstacles). Its Euclidean (power) Voronoi cell is built
  against the neighbours' published virtual generators (``SharedState.virtual``) over the free
  space; the cell's mass centroid is the *virtual target* ``t_virt``.
* Level 2 (Alg. 2): the *real target* ``t_real`` is ``t_virt``, or its projection onto the free
  space when it cannot be reached; the robot drives there with TangentBug
  (:mod:`.bug`) from its scans, while ``g_virt`` moves toward ``t_virt`` at the robot's top
  speed. A goal inside an obstacle is found unreachable by circling the
  obstacle once; the robot then drives to the closest boundary position it recorded (section
  III-A). The completed loop is remembered, so later targets on its obstacle side are
  projected onto it without circling again. A goal in the band along walls that the robot's
  clearance keeps it out of is projected where the robot gets closest to it, without a loop.
* A new ``t_virt`` is computed when the robot has arrived at ``t_real`` and ``g_virt`` at
  ``t_virt``. When that Lloyd step is shorter than the convergence tolerance the robot has
  converged and reports its *final repartition*: the Voronoi cell of its real position among
  the neighbours' real positions (Alg. 1, line 8). Before, it reports its virtual cell.

``Decision.cost`` is always the cost of the real cell about the real position (the coverage the
robots actually achieve); ``TangentBugDetails.cost_virtual`` is the virtual generator's. Their
sums over the team are H of the real and of the virtual generators (Fig. 3); :func:`team_costs`
computes both centrally.

Scan returns on neighbours (within their published ``extra["radius"]``, else the own radius,
plus ``NEIGHBOUR_MASK_MARGIN`` of their published position) are driven through: TangentBug's
reachability test assumes static obstacles, and collisions between robots are the robot node's
safety filter's job. They still bound what the robot sees: the space a neighbour shadows never
counts for leaving a boundary.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.euclidean import EuclideanCell, euclidean_cell
from coverage_ros.core.geodesic.tessellation import Generator
from coverage_ros.core.metrics import euclidean_cost
from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    SharedState,
    Strategy,
    StrategyContext,
    StrategyDetails,
)
from coverage_ros.core.strategies.tangentbug.bug import BugConfig, BugMode, TangentBug
from coverage_ros.core.strategies.tangentbug.scan_geometry import (
    closest_on_polyline,
    on_obstacle_side,
)
from coverage_ros.errors import ConfigError

#: [s] longest time step the virtual generator integrates at once (a pause in the updates must
#: not make it jump).
MAX_VIRTUAL_DT = 1.0
#: [m] scan returns this far beyond a robot radius around a neighbour's published position are
#: that neighbour (covers the lidar's range error and a control period of motion at 0.22 m/s).
NEIGHBOUR_MASK_MARGIN = 0.1
#: [m] two completed loops whose first points are this close (and of equal side) are one.
SAME_LOOP = 0.3
#: A robot that drove toward its target for STUCK_TIME [s] without moving STUCK_DISTANCE [m]
#: is stuck (see TangentBugStrategy._stuck).
STUCK_TIME = 5.0
STUCK_DISTANCE = 0.1
#: [m] two virtual generators closer than this are on one point.
COINCIDENT = 1e-3


@dataclass(frozen=True)
class TangentBugParams:
    """Parameters of the ``tangentbug`` strategy (all in metres)."""

    follow_margin: float = 0.10  # clearance kept from obstacles beyond the robot radius
    lookahead: float = 0.20  # chord of boundary following
    loop_tolerance: float = 0.15  # back this close to the first boundary point = one loop
    leave_margin: float = 0.10  # improvement needed to leave a boundary (TangentBug d_reach)

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                    or v <= 0:
                raise ConfigError.at(f"tangentbug.{f.name}", "must be a finite number > 0 [m]",
                                     v)


@dataclass(frozen=True)
class TangentBugDetails(StrategyDetails):
    cost_real: float  # own real cell's cost about the real position
    cost_virtual: float  # own virtual cell's cost about the virtual generator
    partition: str  # "virtual" until converged, then "real" (the final repartition)
    virtual_generator: np.ndarray | None  # (2,) [m] g_virt
    virtual_target: np.ndarray | None  # (2,) [m] t_virt
    real_target: np.ndarray | None  # (2,) [m] t_real
    projected: bool  # whether t_real is a projection of t_virt
    known_loops: int  # completed loops around obstacles remembered


def team_costs(domain: CoverageDomain, real: np.ndarray, virtual: np.ndarray,
               weights: np.ndarray | None = None) -> tuple[float, float]:
    """``(H_real, H_virtual)``: the Euclidean power-Voronoi coverage cost of the real positions
    ``(n, 2)`` and of the virtual generators ``(n, 2)`` over the free space (each set with its
    own Voronoi partition)."""
    real = np.asarray(real, dtype=np.float64).reshape(-1, 2)
    virtual = np.asarray(virtual, dtype=np.float64).reshape(-1, 2)
    w = np.zeros(len(real)) if weights is None else np.asarray(weights, dtype=np.float64)
    return (euclidean_cost(domain, [Generator(p, float(r)) for p, r in zip(real, w, strict=True)]),
            euclidean_cost(domain, [Generator(p, float(r))
                                    for p, r in zip(virtual, w, strict=True)]))


def decision_costs(decisions: Sequence[Decision]) -> tuple[float, float]:
    """``(H_real, H_virtual)`` summed over a team's decisions (every robot heard all others)."""
    details = [d.details for d in decisions if isinstance(d.details, TangentBugDetails)]
    if len(details) != len(decisions):
        raise ConfigError.at("decision_costs", "needs the decisions of tangentbug robots")
    return (float(sum(x.cost_real for x in details)),
            float(sum(x.cost_virtual for x in details)))


class TangentBugStrategy(Strategy):
    """Breitenmoser et al.'s non-convex coverage (see module docstring)."""

    name: ClassVar[str] = "tangentbug"
    Params: ClassVar[type] = TangentBugParams
    params: TangentBugParams
    needs_scan: ClassVar[bool] = True

    def __init__(self, context: StrategyContext, params: TangentBugParams | None = None) -> None:
        super().__init__(context, params)
        robot = context.robot
        self.bug = TangentBug(BugConfig(
            clearance=robot.radius + self.params.follow_margin, robot_radius=robot.radius,
            v_max=robot.v_max, w_max=robot.w_max,
            goal_tolerance=context.convergence_tolerance, lookahead=self.params.lookahead,
            loop_tolerance=self.params.loop_tolerance, leave_margin=self.params.leave_margin))
        self.virtual: np.ndarray | None = None  # g_virt (2,) [m]
        self.virtual_target: np.ndarray | None = None  # t_virt (2,) [m]
        self.real_target: np.ndarray | None = None  # t_real (2,) [m]
        self.projected = False  # whether t_real is a projection of t_virt
        self._projection_of: np.ndarray | None = None  # the t_virt t_real was projected from
        self.loops: list[tuple[np.ndarray, int]] = []  # completed loops (positions, side)
        self.converged = False
        self._last_time: float | None = None
        self._cells: dict[str, tuple[tuple[object, ...], EuclideanCell]] = {}
        self._heard: set[int] = set()  # neighbours known when the targets were taken
        self._anchor: tuple[np.ndarray, float] | None = None  # (position, time) of progress
        self._unmasked = False  # stuck: the bug sees the neighbours (see _stuck)

    def shared_state(self, obs: Observation) -> SharedState:
        g = obs.position.copy() if self.virtual is None else self.virtual.copy()
        return SharedState(position=obs.position.copy(), weight=self.context.weight, virtual=g)

    # ------------------------------------------------------------------ level 1 + 2
    def update(self, obs: Observation, neighbours: Sequence[Neighbour]) -> Decision:
        ctx, x = self.context, obs.position
        if self.virtual is None:
            self.virtual = x.copy()  # Alg. 1 line 1: g_virt <- p_S
        dt = 0.0 if self._last_time is None else min(max(obs.time - self._last_time, 0.0),
                                                     MAX_VIRTUAL_DT)
        self._last_time = obs.time
        self._advance_virtual(ctx.robot.v_max * dt)
        vcell = self._cell("virtual", self.virtual, [
            Generator(n.state.virtual if n.state.virtual is not None else n.position,
                      n.state.weight) for n in neighbours])
        rcell = self._cell("real", x, [Generator(n.position, n.state.weight)
                                       for n in neighbours])
        heard = {n.robot_id for n in neighbours}
        retarget = not heard <= self._heard
        if self._coincident(neighbours):
            # Two virtual generators on one point share one cell and one centroid for ever
            # (Lloyd cannot part them): start this one again from the robot (Alg. 1 line 1).
            self.virtual = x.copy()
            vcell = self._cell("virtual", self.virtual, [
                Generator(n.state.virtual if n.state.virtual is not None else n.position,
                          n.state.weight) for n in neighbours])
            self.virtual_target, retarget = None, True
        if (self.bug.done and self._virtual_arrived()) or retarget:
            # A target taken before some neighbours were heard (a robot's first update may
            # come before their states do: its cell was then the whole map) is taken again.
            self._remember_loop()
            self._heard = heard
            self._next_targets(x, vcell.centroid)
            self._anchor = None  # arriving is progress: the stuck clock starts again
        velocity, heading = (0.0, 0.0), None
        stuck = self._stuck(x, obs.time)
        if obs.scan is not None and not self.bug.done:
            pts, hidden = obs.scan.points(obs.scan_origin), None
            if not stuck:
                keep = _off_neighbours(pts, neighbours, ctx.robot.radius)
                pts, hidden = pts[keep], pts[~keep]
            cmd = self.bug.step(obs.pose, pts, obs.scan.range_max, hidden)
            velocity = (cmd.v, cmd.w)
            if cmd.v > 0.0 or cmd.w != 0.0:
                heading = cmd.heading
            if self.bug.mode is BugMode.PROJECTED:
                self.real_target, self.projected = self.bug.target.copy(), True
                self._projection_of = self.virtual_target
        part = rcell if self.converged else vcell
        shared = SharedState(position=x.copy(), weight=ctx.weight, mass=part.mass,
                             virtual=self.virtual.copy(),
                             extra={"cost_real": rcell.cost, "cost_virtual": vcell.cost,
                                    "converged": float(self.converged)})
        return Decision(
            goal=None, velocity=velocity, cell=part.nodes, shared=shared,
            converged=self.converged, cost=rcell.cost, mass=part.mass,
            target=None if self.real_target is None else self.real_target.copy(),
            mode=self.bug.mode.value, cell_polygon=part.polygon,
            details=self._details(vcell.cost, rcell.cost), heading=heading)

    def _coincident(self, neighbours: Sequence[Neighbour]) -> bool:
        """Whether a neighbour's virtual generator is on this one's (within COINCIDENT)."""
        return any(n.state.virtual is not None and
                   float(np.hypot(*(n.state.virtual - self.virtual))) < COINCIDENT
                   for n in neighbours)

    def _stuck(self, x: np.ndarray, now: float) -> bool:
        """Whether the robot has been driving toward its target without getting anywhere for
        STUCK_TIME: TangentBug plans through the neighbours (their returns are masked), so
        two robots that meet head-on round an obstacle - each stopped by the other in the
        robot node's safety filter - would wait for each other for ever. A stuck robot's bug
        sees its neighbours as the obstacles they are until it has moved on."""
        if self.bug.done or self._anchor is None or \
                float(np.hypot(*(x - self._anchor[0]))) > STUCK_DISTANCE:
            self._anchor = (x.copy(), now)
            self._unmasked = False
        elif now - self._anchor[1] > STUCK_TIME:
            self._unmasked = True
        return self._unmasked

    def _cell(self, kind: str, position: np.ndarray, others: list[Generator]) -> EuclideanCell:
        """The own power cell of ``position`` among ``others``; reused while neither moved
        (virtual generators wait at their targets while the robots drive)."""
        key = (tuple(position), tuple((*o.position, o.weight) for o in others))
        cached = self._cells.get(kind)
        if cached is not None and cached[0] == key:
            return cached[1]
        cell = euclidean_cell(self.context.domain, Generator(position, self.context.weight),
                              others)
        self._cells[kind] = (key, cell)
        return cell

    def _advance_virtual(self, step: float) -> None:
        """Alg. 2 line 6: the virtual generator moves straight toward t_virt."""
        assert self.virtual is not None
        if self.virtual_target is None:
            return
        d = self.virtual_target - self.virtual
        dist = float(np.hypot(*d))
        if dist <= step:
            self.virtual = self.virtual_target.copy()
        else:
            self.virtual = self.virtual + d * (step / dist)

    def _virtual_arrived(self) -> bool:
        return self.virtual_target is None or bool(np.all(self.virtual == self.virtual_target))

    def _next_targets(self, x: np.ndarray, centroid: np.ndarray) -> None:
        """Alg. 1 lines 4-5 and Alg. 2 lines 2-4: new virtual target, its real target."""
        assert self.virtual is not None
        tol = self.context.convergence_tolerance
        lloyd_step = float(np.hypot(*(centroid - self.virtual)))
        self.virtual_target = centroid.copy()
        real, projected = self._project_known(centroid)
        if self.projected and self._projection_of is not None and \
                self.real_target is not None and \
                float(np.hypot(*(centroid - self._projection_of))) < tol:
            # Keep the projection found for (nearly) this target: the remembered loop's
            # closest point may lie in the band the clearance keeps the robot out of, and
            # re-projected on the spot at every update the robot would never converge. Kept
            # against the target it was found for, so that creeping targets are followed.
            real, projected = self.real_target, True
        else:
            self._projection_of = centroid.copy() if projected else None
        self.real_target, self.projected = real, projected
        if float(np.hypot(*(real - x))) > tol:
            self.bug.reset(real)
            self.converged = False
        else:
            self.converged = lloyd_step < tol

    def _project_known(self, target: np.ndarray) -> tuple[np.ndarray, bool]:
        """``t_virt`` projected onto a remembered loop it lies behind, else itself."""
        best: np.ndarray | None = None
        for loop, side in self.loops:
            if on_obstacle_side(loop, side, target[None])[0]:
                q = closest_on_polyline(loop, target)
                if best is None or np.hypot(*(q - target)) < np.hypot(*(best - target)):
                    best = q
        return (target.copy(), False) if best is None else (best, True)

    def _remember_loop(self) -> None:
        bug = self.bug
        if bug.mode is not BugMode.PROJECTED or bug.loop is None:
            return
        for loop, side in self.loops:
            if side == bug.loop_side and np.hypot(*(loop[0] - bug.loop[0])) < SAME_LOOP:
                return
        self.loops.append((bug.loop.copy(), bug.loop_side))

    def _details(self, cost_virtual: float, cost_real: float) -> TangentBugDetails:
        def copy(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a.copy()

        return TangentBugDetails(
            cost_real=cost_real, cost_virtual=cost_virtual,
            partition="real" if self.converged else "virtual",
            virtual_generator=copy(self.virtual), virtual_target=copy(self.virtual_target),
            real_target=copy(self.real_target), projected=self.projected,
            known_loops=len(self.loops))


def _off_neighbours(points: np.ndarray, neighbours: Sequence[Neighbour],
                    radius: float) -> np.ndarray:
    """``(M,) bool``: which scan returns ``(M, 2)`` are off the neighbours' bodies (their
    published ``extra["radius"]``, else ``radius``)."""
    if len(neighbours) == 0 or len(points) == 0:
        return np.ones(len(points), dtype=bool)
    P = np.array([n.position for n in neighbours], dtype=np.float64)
    r = np.array([float(n.state.extra.get("radius", radius)) for n in neighbours])
    d2 = ((points[:, None, :] - P[None, :, :]) ** 2).sum(axis=-1)
    off: np.ndarray = (d2 > (r + NEIGHBOUR_MASK_MARGIN) ** 2).all(axis=1)
    return off
