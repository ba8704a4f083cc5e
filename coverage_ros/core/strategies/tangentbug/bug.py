"""TangentBug on a planar range scan, with Breitenmoser et al.'s reachability test and projection.

TangentBug (Kamon, Rivlin & Rimon 1998; Choset et al., *Principles of Robot Motion*, 2.3)
steers a robot to a goal from range readings and its pose alone. Breitenmoser et al. (2010,
section III-A) use it as the level-2 planner of Voronoi coverage and extends it: when the
goal is unreachable (inside an obstacle), the robot circles the obstacle once, remembers the
boundary position closest to the goal, and drives there - the optimal projection of the goal
onto the free space (their section IV-B).

The robot is a disc. The planner works in the configuration space of a point that keeps
``clearance`` [m] from every scan return: the *free length* ``L(u)`` of a direction ``u`` is how
far the point can move along ``u`` before it comes closer than ``clearance`` to a return
(:func:`free_lengths`), evaluated on ``DIRECTIONS`` fixed map-frame directions.

Behaviours (:class:`BugMode`):

* motion-to-goal - straight to the goal when its ray is free (up to the sensing horizon, or to
  within ``goal_tolerance`` of the goal); else
  toward the node ``O`` (an endpoint of a visible obstacle segment, :func:`scan_nodes`) that
  minimises the heuristic ``|x - O| + |O - goal|``; once a side of the goal ray is chosen the
  robot keeps to it while that side has nodes (the heuristic of nodes near a silhouette flickers
  with the beams' alignment, which would make the robot dither on the spot). When the node lies
  more than 90 degrees from the goal direction (moving toward it would increase the distance to
  the goal), the robot is at a local minimum and switches to
* boundary-following - keep the obstacle on one side at ``clearance`` (sweep from the nearest
  return away from it to the first direction free for ``lookahead`` metres). ``d_followed`` is the
  smallest distance to the goal seen while following; ``d_reach`` the smallest distance to the
  goal of the visible free space. The robot leaves the boundary when the line to the goal is
  free (all of it: a ray free only up to the horizon does not count) or
  ``d_reach < d_followed - min(leave_margin, d_followed / 2)`` and heads for that point. Back
  within ``loop_tolerance`` of where it first touched the boundary, having enclosed an area,
  the goal is unreachable: it turns to
* projecting - follow the boundary the shorter way to the recorded closest position and stop
  there (``PROJECTED``).

A goal that is not free but closer than ``clearance`` to the robot, with no visible free point
closer to it, is projected on the spot (``PROJECTED`` without a loop): it lies in the band the
clearance keeps free along every wall (the paper's point robots have no such band), and
circling would mean following the whole arena wall to move a few centimetres.

All points are ``(N, 2) float64`` in metres, map frame; angles in radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from coverage_ros.core.strategies.tangentbug.boundary import BoundaryRun
from coverage_ros.core.strategies.tangentbug.scan_geometry import (
    closest_on_rays,
    free_lengths,
    scan_nodes,
    unit_directions,
)
from coverage_ros.core.strategies.tangentbug.steering import SAFETY_MARGIN, steer
from coverage_ros.errors import ConfigError

#: Fixed map-frame directions on which free lengths are evaluated (1 degree apart: as fine
#: as the LDS-01's beams, so no gap the robot fits through falls between two directions).
DIRECTIONS = 360
#: A range jump of this many clearances between returns adjacent in bearing is an obstacle endpoint
#: (a gap the robot's clearance disc could enter).
NODE_JUMP_CLEARANCES = 2.0
#: A projection run that travels this many loop lengths without reaching the recorded point
#: falls back to motion-to-goal toward it (it is reachable: the robot was there).
PROJECTION_LOOPS = 1.5


class BugMode(StrEnum):
    MOTION_TO_GOAL = "motion_to_goal"
    BOUNDARY_FOLLOWING = "boundary_following"
    PROJECTING = "projecting"  # goal unreachable: on the way to the recorded closest point
    REACHED = "reached"
    PROJECTED = "projected"  # stopped at the closest reachable boundary point
    BLOCKED = "blocked"  # no free direction at all


@dataclass(frozen=True)
class BugConfig:
    """TangentBug parameters (validated)."""

    clearance: float  # [m] follow distance from obstacle surfaces (robot radius + margin)
    robot_radius: float  # [m] for the brake
    v_max: float  # [m/s]
    w_max: float  # [rad/s]
    goal_tolerance: float = 0.05  # [m] arrival radius
    lookahead: float = 0.20  # [m] boundary-following chord
    loop_tolerance: float = 0.15  # [m] back this close to the first boundary point = one loop
    leave_margin: float = 0.10  # [m] required improvement of d_reach over d_followed

    def __post_init__(self) -> None:
        for name in ("clearance", "robot_radius", "v_max", "w_max", "goal_tolerance",
                     "lookahead", "loop_tolerance", "leave_margin"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                    or v <= 0:
                raise ConfigError.at(name, "must be a finite number > 0", v)
        if self.clearance <= self.robot_radius + SAFETY_MARGIN:  # else the brake stalls it
            raise ConfigError.at("clearance", "must exceed the robot radius + SAFETY_MARGIN",
                                 self.clearance, f"> {self.robot_radius + SAFETY_MARGIN}")
        if self.loop_tolerance < self.goal_tolerance:
            raise ConfigError.at("loop_tolerance", "must be >= goal_tolerance",
                                 self.loop_tolerance, f">= {self.goal_tolerance}")


@dataclass(frozen=True)
class BugCommand:
    v: float  # [m/s]
    w: float  # [rad/s]
    mode: BugMode
    heading: float  # [rad] desired heading (map frame)


class TangentBug:
    """One robot's TangentBug state machine; call :meth:`reset` with a goal, then :meth:`step`
    every control period with the pose and the scan's map-frame hit points.

    After ``PROJECTED``, :attr:`best` is the projection of the goal, :attr:`loop` ``(K, 2)``
    the positions of the completed loop and :attr:`loop_side` the side the obstacle was on
    (+1 left), for :func:`on_obstacle_side`.
    """

    def __init__(self, config: BugConfig) -> None:
        self.config = config
        self._dirs = unit_directions(DIRECTIONS)
        # Returns bounding the leave test's view (hidden ones too: see step), free lengths.
        self._seen_rel, self._seen = np.zeros((0, 2)), np.zeros(DIRECTIONS)
        self.goal = np.zeros(2)
        self.reset(None)

    # ------------------------------------------------------------------ public state
    def reset(self, goal: np.ndarray | None) -> None:
        """Start over toward ``goal`` (``None``: stay, mode ``REACHED``)."""
        if goal is not None:
            self.goal = np.asarray(goal, dtype=np.float64).reshape(2).copy()
        self.mode = BugMode.REACHED if goal is None else BugMode.MOTION_TO_GOAL
        self.target = self.goal.copy()  # the goal, or its projection once unreachable
        self.unreachable = False
        self.best: np.ndarray | None = None  # closest boundary position to the goal so far
        self.loop: np.ndarray | None = None  # (K, 2) positions of the completed loop
        self.loop_side = 0
        self._loop_length = 0.0
        self._leave_point: np.ndarray | None = None
        self._node_side = 0
        self._run = BoundaryRun(1)

    @property
    def done(self) -> bool:
        return self.mode in (BugMode.REACHED, BugMode.PROJECTED)

    # ------------------------------------------------------------------ one control period
    def step(self, pose: np.ndarray, points: np.ndarray, horizon: float,
             hidden: np.ndarray | None = None) -> BugCommand:
        """``pose (x, y, yaw)``; ``points (M, 2)`` scan returns (map frame); ``horizon`` [m]:
        the sensing range (space beyond it counts as free); ``hidden (K, 2)``: returns left
        out of ``points`` (on neighbour robots: driven through, but not seen past - the space
        they shadow is not known to be free, so it never counts for leaving a boundary)."""
        c, x, yaw = self.config, np.asarray(pose[:2], dtype=np.float64), float(pose[2])
        if self.done:
            return BugCommand(0.0, 0.0, self.mode, yaw)
        if self.mode is BugMode.BLOCKED:
            self.mode = BugMode.MOTION_TO_GOAL  # try again
        if float(np.hypot(*(self.target - x))) <= c.goal_tolerance:
            self.mode = BugMode.PROJECTED if self.unreachable else BugMode.REACHED
            return BugCommand(0.0, 0.0, self.mode, yaw)
        rel = np.asarray(points, dtype=np.float64).reshape(-1, 2) - x
        reach = max(float(horizon) - c.clearance, 0.0)
        L = free_lengths(rel, self._dirs, c.clearance, reach)
        self._seen_rel, self._seen = rel, L
        if hidden is not None and len(hidden):
            self._seen_rel = np.vstack([rel, np.asarray(hidden, dtype=np.float64) - x])
            self._seen = free_lengths(self._seen_rel, self._dirs, c.clearance, reach)
        if not self.unreachable and self._in_reach_of_band(x, rel, L, reach):
            return BugCommand(0.0, 0.0, self.mode, yaw)
        heading: float | None = None
        approach: float | None = None
        if self.mode is BugMode.MOTION_TO_GOAL:
            heading, approach = self._motion_to_goal(x, rel, L, reach)
        if self.mode is BugMode.BOUNDARY_FOLLOWING:
            heading = self._follow(x, rel, L, reach)
            # (_follow changes the mode when it leaves the boundary)
            if self.mode is BugMode.MOTION_TO_GOAL:  # type: ignore[comparison-overlap]
                heading, approach = self._motion_to_goal(x, rel, L, reach)
        if self.mode is BugMode.PROJECTING:
            heading, approach = self._project(x, rel, L, reach)
        if heading is None:
            self.mode = BugMode.BLOCKED
            return BugCommand(0.0, 0.0, self.mode, yaw)
        return self._drive(yaw, heading, rel, reach, approach)

    def _goal_visible(self, x: np.ndarray, rel: np.ndarray, reach: float,
                      horizon_counts: bool = True) -> bool:
        """Whether the straight line to the goal is free up to within ``goal_tolerance`` of
        the goal, or (``horizon_counts``) up to the sensing horizon."""
        c = self.config
        to_goal = self.target - x
        d = float(np.hypot(*to_goal))
        free = float(free_lengths(rel, (to_goal / d)[None], c.clearance, reach)[0])
        return free >= (min(d - c.goal_tolerance, reach) if horizon_counts
                        else d - c.goal_tolerance) - 1e-9

    def _in_reach_of_band(self, x: np.ndarray, rel: np.ndarray, L: np.ndarray,
                          reach: float) -> bool:
        """A goal closer than ``clearance`` to the robot but not free (it lies in the band the
        clearance keeps the robot out of) is projected where the robot stands when no visible
        free point is closer to it: the projection is then within ``clearance`` of the goal
        (no need to circle a whole obstacle - or the whole arena - to find it)."""
        c = self.config
        to_goal = self.target - x
        d = float(np.hypot(*to_goal))
        if d >= c.clearance or self._goal_visible(x, rel, reach):
            return False
        if closest_on_rays(x, self._dirs, L, self.target)[0] < d - c.goal_tolerance:
            return False
        self.mode, self.unreachable = BugMode.PROJECTED, True
        self.best, self.target = x.copy(), x.copy()
        return True

    # ------------------------------------------------------------------ behaviours
    def _motion_to_goal(self, x: np.ndarray, rel: np.ndarray, L: np.ndarray,
                        reach: float) -> tuple[float | None, float | None]:
        c = self.config
        to_goal = self.target - x
        d_goal = float(np.hypot(*to_goal))
        u_goal = to_goal / d_goal
        if self._goal_visible(x, rel, reach):
            self._leave_point = None
            self._node_side = 0
            return math.atan2(u_goal[1], u_goal[0]), (d_goal if d_goal <= reach else None)
        if self._leave_point is not None:
            to_leave = self._leave_point - x
            d_leave = float(np.hypot(*to_leave))
            if d_leave > c.goal_tolerance:
                return math.atan2(to_leave[1], to_leave[0]), d_leave
            self._leave_point = None
        node = self._best_node(x, rel, L, u_goal)
        if node is None or float(node @ u_goal) <= 0.0:
            # Local minimum of the distance to the goal: go around the blocking obstacle on the
            # side of the best node (a node left of the goal ray = obstacle on the right).
            side = 1
            if node is not None:
                side = -1 if u_goal[0] * node[1] - u_goal[1] * node[0] > 0 else 1
            self.mode = BugMode.BOUNDARY_FOLLOWING
            self._run = BoundaryRun(side)
            return None, None
        return math.atan2(node[1], node[0]), None

    def _best_node(self, x: np.ndarray, rel: np.ndarray, L: np.ndarray,
                   u_goal: np.ndarray) -> np.ndarray | None:
        """Unit heading toward the endpoint node ``O`` minimising ``|x - O| + |O - goal|``
        (:func:`scan_nodes`), turned toward its open side until free for ``|x - O|``."""
        c = self.config
        nodes, opens = scan_nodes(rel, c.clearance, NODE_JUMP_CLEARANCES * c.clearance)
        if len(nodes) == 0:
            return None
        h = np.hypot(*nodes.T) + np.hypot(*(self.target - x - nodes).T)
        side = np.sign(u_goal[0] * nodes[:, 1] - u_goal[1] * nodes[:, 0])
        order = list(np.argsort(h))
        if self._node_side:
            # Committed to a side of the goal ray: go on round the obstacle that way (node
            # depths near a silhouette flicker with the beams' alignment as the robot turns).
            order = [k for k in order if side[k] == self._node_side] + [
                k for k in order if side[k] != self._node_side]
        K = len(L)
        for k in order:
            need = min(float(np.hypot(*nodes[k])), float(L.max()))
            k0 = int(round(math.atan2(nodes[k, 1], nodes[k, 0]) / (2.0 * math.pi) * K))
            ks = (k0 + int(opens[k]) * np.arange(K // 4)) % K
            ok = np.flatnonzero(L[ks] >= need - 1e-9)
            if len(ok):
                self._node_side = int(side[k])
                heading: np.ndarray = self._dirs[ks[ok[0]]]
                return heading
        return None

    def _follow(self, x: np.ndarray, rel: np.ndarray, L: np.ndarray,
                reach: float) -> float | None:
        """Boundary-following heading. While following (not projecting) it records the trace
        and the best point, closes loops and checks the leave condition."""
        c = self.config
        if len(rel) == 0:
            self.mode = BugMode.MOTION_TO_GOAL  # nothing left to follow
            return None
        dist = np.hypot(*rel.T)
        near = int(np.argmin(dist))
        run = self._run
        if self.mode is BugMode.BOUNDARY_FOLLOWING:
            if run.anchor is None and dist[near] <= c.clearance + 0.5 * c.loop_tolerance:
                run.touch(x)
            if run.anchor is not None:
                loop = run.record(x, self.target, c.loop_tolerance)
                if run.best is not None:
                    self.best = run.best
                if loop is not None:
                    self._close_loop(loop)
                    return None
            # Leave for a goal really in sight or a seen point closer than any followed (a ray
            # free only to the horizon, or through a neighbour's shadow, would bring the robot
            # back to the same boundary to follow it afresh, for ever).
            d_reach, point = closest_on_rays(x, self._dirs, self._seen, self.target)
            d_followed = min(run.best_d, float(np.hypot(*(self.target - x))))
            if self._goal_visible(x, self._seen_rel, reach, horizon_counts=False) or (
                    d_reach < d_followed - min(c.leave_margin, 0.5 * d_followed)):
                self.mode = BugMode.MOTION_TO_GOAL
                self._leave_point = point
                self._node_side = 0
                return None
        K = len(L)
        k0 = int(round(math.atan2(rel[near, 1], rel[near, 0]) / (2.0 * math.pi) * K)) % K
        ks = (k0 - run.side * np.arange(K)) % K
        ok = np.flatnonzero(L[ks] >= min(c.lookahead, reach) - 1e-9)
        if len(ok) == 0:
            return None
        d = self._dirs[ks[ok[0]]]
        return math.atan2(d[1], d[0])

    def _close_loop(self, trace: np.ndarray) -> None:
        """One full loop without a leave point: the goal is unreachable. Head for the best
        point the shorter way round."""
        run = self._run
        self.loop, self.loop_side = trace, run.side
        self._loop_length = run.travelled
        side = run.side if run.best_s <= 0.5 * run.travelled else -run.side
        self.mode = BugMode.PROJECTING
        self.unreachable = True
        self._run = BoundaryRun(side)
        self._run.move_to(trace[-1])
        assert self.best is not None
        self.target = self.best.copy()

    def _project(self, x: np.ndarray, rel: np.ndarray, L: np.ndarray,
                 reach: float) -> tuple[float | None, float | None]:
        c = self.config
        to_best = self.target - x
        d = float(np.hypot(*to_best))
        self._run.move_to(x)
        if d <= c.loop_tolerance:
            return math.atan2(to_best[1], to_best[0]), d
        if self._run.travelled > PROJECTION_LOOPS * self._loop_length:
            # Lost the contour: the point is reachable (the robot was there), go by TangentBug.
            self.mode = BugMode.MOTION_TO_GOAL
            return self._motion_to_goal(x, rel, L, reach)
        return self._follow(x, rel, L, reach), None

    # ------------------------------------------------------------------ actuation
    def _drive(self, yaw: float, heading: float, rel: np.ndarray, reach: float,
               approach: float | None) -> BugCommand:
        c = self.config
        v, w = steer(yaw, heading, rel, reach, approach, c.v_max, c.w_max, c.robot_radius,
                     c.lookahead)
        return BugCommand(v, w, self.mode, heading)
