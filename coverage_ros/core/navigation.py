"""Local navigation of a differential-drive robot toward its coverage goal.

* :func:`plan_path` - the shortest path on the configuration-space graph (free cells inflated by
  the robot radius) from the robot to its goal, shortened by line of sight into a few waypoints
  (the straight segment when it is free, which is the usual case: strategies clip their goals
  to what the robot can see).
* :class:`PathTracker` - pure pursuit: steer toward a look-ahead point on the path, turn in
  place when it lies far off the heading, slow down near the goal; velocities limited to
  ``v_max``/``w_max`` and changes to ``a_max``/``alpha_max``.
* :class:`SafetyFilter` - the last word on every command: the unicycle arc of (v, w) over the
  stopping horizon is simulated against the configuration space (walls), the neighbours'
  discs and the lidar points, and v is cut (to zero if need be; turning in place is always
  allowed for a disc robot) until the arc is clear. No command ever drives into a wall.

Poses are ``(x, y, yaw)`` in the map frame [m, rad]; paths are ``(M, 2)`` map-frame points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.domain import CoverageDomain
from coverage_ros.core.geometry import wrap_angle
from coverage_ros.core.local_search import BLOCK, build_local_graph, local_graph_for
from coverage_ros.core.world import RobotSpec
from coverage_ros.errors import ConfigError

#: Fraction of a cell between collision checks along a segment or arc.
CHECK_STEP_CELLS = 0.25
#: [m] extra clearance beyond the robot radius that planned shortcuts keep from walls (pure
#: pursuit cuts corners a little; this keeps the robot off them).
PATH_MARGIN = 0.05
#: [m] the first path search looks this far around the box of start and goal.
PLAN_WINDOW_MARGIN = 2.0
#: v scales tried by the safety filter, largest first (0 is always safe).
SAFE_SCALES = (1.0, 0.6, 0.3, 0.12, 0.0)


def segment_free(domain: CoverageDomain, a: np.ndarray, b: np.ndarray,
                 margin: float = 0.0) -> bool:
    """Whether every point of the segment a-b (map frame) lies on a free C-space cell, and
    (``margin`` > 0) at least ``margin`` farther from obstacles than the C-space requires."""
    ga, gb = domain.to_grid(np.stack([a, b]))
    n = max(2, int(math.ceil(float(np.hypot(*(gb - ga))) / CHECK_STEP_CELLS)) + 1)
    t = np.linspace(0.0, 1.0, n)[:, None]
    pts = ga + t * (gb - ga)
    if not points_free(domain, pts):
        return False
    if margin <= 0:
        return True
    cells = np.floor(pts[:, ::-1]).astype(np.int64)
    need = domain.robot_radius + 0.5 * domain.resolution + margin
    return bool((domain.clearance[cells[:, 0], cells[:, 1]] >= need).all())


def points_free(domain: CoverageDomain, grid_pts: np.ndarray) -> bool:
    H, W = domain.shape
    c = np.floor(grid_pts[:, 0]).astype(np.int64)
    r = np.floor(grid_pts[:, 1]).astype(np.int64)
    inside = (r >= 0) & (r < H) & (c >= 0) & (c < W)
    return bool(inside.all() and domain.free[r, c].all())


def plan_path(domain: CoverageDomain, start: np.ndarray, goal: np.ndarray,
              max_detour: float = 4.0) -> np.ndarray | None:
    """``(M, 2)`` waypoints from ``start`` to ``goal`` (both included), or None when the goal
    cannot be reached within ``max_detour`` times the straight-line distance (+ 2 m)."""
    start = np.asarray(start, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    if segment_free(domain, start, goal, PATH_MARGIN) or (
            float(np.hypot(*(goal - start))) < 4 * domain.resolution
            and segment_free(domain, start, goal)):
        return np.stack([start, goal])
    limit = max_detour * float(np.hypot(*(goal - start))) + 2.0
    # First a window around start and goal (paths to a coverage goal are short), then the
    # whole map.
    for window in (PLAN_WINDOW_MARGIN, None):
        local = _planning_graph(domain, start, goal, window)
        nodes, costs, _ = domain.snap(start)
        csr = local.with_sources([(local.local_of(nodes), costs)])
        dist, pred = dijkstra(csr, directed=True, indices=local.n + 1, limit=limit,
                              return_predecessors=True)
        lids = local.local_of(domain.snap(goal)[0])
        lids = lids[lids > 0]
        if len(lids) and np.isfinite(dist[lids]).any():
            break
    else:
        return None
    v = int(lids[np.argmin(dist[lids])])
    chain = []
    while 0 < v <= local.n:
        chain.append(int(local.global_nodes[v - 1]))
        v = int(pred[v])
    cells = domain.to_map(domain.node_centers(np.array(chain[::-1], dtype=np.int64)))
    return shortcut(domain, np.vstack([start, cells, goal]))


def _planning_graph(domain: CoverageDomain, start: np.ndarray, goal: np.ndarray,
                    margin: float | None):
    """The search graph of the box around start and goal grown by ``margin`` [m] (None: the
    whole domain)."""
    if margin is None or any(domain.graph.wrap):
        return local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1), math.inf)
    g = domain.to_grid(np.stack([start, goal]))
    m = margin / domain.resolution
    H, W = domain.shape
    Hb, Wb = -(-H // BLOCK), -(-W // BLOCK)
    blocks = np.zeros((Hb, Wb), dtype=bool)
    r0, r1 = (int(np.clip((g[:, 1].min() - m) // BLOCK, 0, Hb)),
              int(np.clip((g[:, 1].max() + m) // BLOCK + 1, 0, Hb)))
    c0, c1 = (int(np.clip((g[:, 0].min() - m) // BLOCK, 0, Wb)),
              int(np.clip((g[:, 0].max() + m) // BLOCK + 1, 0, Wb)))
    blocks[r0:r1, c0:c1] = True
    return build_local_graph(domain, blocks)


def shortcut(domain: CoverageDomain, path: np.ndarray) -> np.ndarray:
    """Greedy line-of-sight shortening: from each waypoint, jump to the farthest one reachable
    in a straight line that keeps :data:`PATH_MARGIN` from the walls (else the next one)."""
    out = [path[0]]
    i = 0
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1 and not segment_free(domain, path[i], path[j], PATH_MARGIN):
            j -= 1
        out.append(path[j])
        i = j
    return np.array(out)


@dataclass(frozen=True)
class TrackerConfig:
    v_max: float = RobotSpec().v_max  # [m/s]
    w_max: float = RobotSpec().w_max  # [rad/s]
    a_max: float = RobotSpec().a_max  # [m/s^2]
    alpha_max: float = RobotSpec().alpha_max  # [rad/s^2]
    lookahead: float = 0.25  # [m] carrot distance along the path
    goal_tolerance: float = 0.05  # [m] closer than this = arrived
    heading_gain: float = 2.5  # [1/s] w = gain * heading error
    turn_in_place: float = 1.0  # [rad] heading error above which the robot only turns
    slow_radius: float = 0.4  # [m] speed ramps down inside this distance of the goal

    def __post_init__(self) -> None:
        for name in ("v_max", "w_max", "a_max", "alpha_max", "lookahead", "goal_tolerance",
                     "heading_gain", "turn_in_place", "slow_radius"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError.at(name, "must be a finite number > 0", v)

    @classmethod
    def for_robot(cls, robot: RobotSpec, **kw) -> TrackerConfig:
        return cls(v_max=robot.v_max, w_max=robot.w_max, a_max=robot.a_max,
                   alpha_max=robot.alpha_max, **kw)


class PathTracker:
    """Pure pursuit with speed and acceleration limits (see module docstring)."""

    def __init__(self, config: TrackerConfig) -> None:
        self.config = config
        self.v = 0.0
        self.w = 0.0

    def reset(self) -> None:
        self.v = self.w = 0.0

    def command(self, pose: np.ndarray, path: np.ndarray | None, dt: float,
                ) -> tuple[float, float, bool]:
        """``(v, w, arrived)`` for this control step of ``dt`` seconds."""
        c = self.config
        if path is None or len(path) == 0:
            return self._limit(0.0, 0.0, dt) + (True,)
        p = np.asarray(pose[:2], dtype=np.float64)
        goal = path[-1]
        to_goal = float(np.hypot(*(goal - p)))
        if to_goal < c.goal_tolerance:
            return self._limit(0.0, 0.0, dt) + (True,)
        target = carrot(path, p, c.lookahead)
        error = float(wrap_angle(math.atan2(target[1] - p[1], target[0] - p[0]) - pose[2]))
        w = float(np.clip(c.heading_gain * error, -c.w_max, c.w_max))
        if abs(error) > c.turn_in_place:
            v = 0.0
        else:
            v = c.v_max * math.cos(error) * min(1.0, to_goal / c.slow_radius)
            v = max(v, 0.0)
        return self._limit(v, w, dt) + (False,)

    def _limit(self, v: float, w: float, dt: float) -> tuple[float, float]:
        c = self.config
        self.v = float(np.clip(v, self.v - c.a_max * dt, self.v + c.a_max * dt))
        self.w = float(np.clip(w, self.w - c.alpha_max * dt, self.w + c.alpha_max * dt))
        self.v = float(np.clip(self.v, -c.v_max, c.v_max))
        self.w = float(np.clip(self.w, -c.w_max, c.w_max))
        return self.v, self.w

    def override(self, v: float, w: float) -> None:
        """Tell the tracker what was really commanded (after the safety filter)."""
        self.v, self.w = float(v), float(w)


def carrot(path: np.ndarray, p: np.ndarray, lookahead: float) -> np.ndarray:
    """The point ``lookahead`` metres along the path beyond the point of the path nearest to
    ``p`` (the goal if the path ends sooner)."""
    if len(path) == 1:
        return path[0]
    a, b = path[:-1], path[1:]
    ab = b - a
    L2 = np.maximum((ab * ab).sum(axis=1), 1e-12)
    t = np.clip(((p - a) * ab).sum(axis=1) / L2, 0.0, 1.0)
    d = np.hypot(*(a + t[:, None] * ab - p).T)
    k = int(np.argmin(d))
    seg_len = np.sqrt(L2)
    pos = t[k] * seg_len[k]
    # The carrot stays on the current segment: looking past a corner would cut it.
    if seg_len[k] - pos >= lookahead:
        return a[k] + ab[k] * ((pos + lookahead) / seg_len[k])
    if seg_len[k] - pos > 0.5 * lookahead or k == len(ab) - 1:
        return b[k]
    nxt = k + 1  # nearly at the corner: start along the next segment
    return a[nxt] + ab[nxt] * min(1.0, (lookahead - (seg_len[k] - pos)) / seg_len[nxt])


@dataclass(frozen=True)
class SafetyConfig:
    radius: float = RobotSpec().radius  # [m] own body
    robot_margin: float = 0.06  # [m] kept free between two robots' bodies
    # [m] kept free to lidar points. Small on purpose: walls are already kept at the
    # configuration space's clearance (measured between cell centres, which lets a path pass a
    # real wall edge ~1 cm closer than radius + 3 cm); the scan check is for what the map lacks.
    obstacle_margin: float = 0.01
    horizon: float = 0.6  # [s] arc simulated beyond the stopping distance
    a_max: float = RobotSpec().a_max  # [m/s^2] braking


class SafetyFilter:
    """Cuts v until the predicted arc is clear (see module docstring)."""

    def __init__(self, domain: CoverageDomain, config: SafetyConfig) -> None:
        self.domain = domain
        self.config = config
        # [m] distance of every cell centre to the nearest obstacle cell (true map), and the
        # clearance a robot centre needs (what the configuration space is inflated by).
        self.clearance = domain.geometry.clearance()
        self.needed = config.radius + 0.5 * domain.resolution

    def filter(self, pose: np.ndarray, v: float, w: float,
               neighbours: np.ndarray | None = None, neighbour_radii: np.ndarray | None = None,
               scan_points: np.ndarray | None = None) -> tuple[float, float, str]:
        """``(v, w, reason)``; reason is "" when the command passed unchanged."""
        why = ""
        for scale in SAFE_SCALES:
            vs = v * scale
            blocked = self._blocked(pose, vs, w, neighbours, neighbour_radii, scan_points)
            if not blocked:
                return vs, w, "" if scale == 1.0 else f"slowed: {why}"
            why = blocked
        return 0.0, w, f"stopped: {why}"

    def _arc(self, pose: np.ndarray, v: float, w: float) -> np.ndarray:
        c = self.config
        T = c.horizon + abs(v) / c.a_max
        length = abs(v) * T
        n = max(2, int(math.ceil(length / (CHECK_STEP_CELLS * self.domain.resolution))) + 1)
        t = np.linspace(0.0, T, n)
        yaw = pose[2] + w * t
        if abs(w) < 1e-6:
            x = pose[0] + v * t * math.cos(pose[2])
            y = pose[1] + v * t * math.sin(pose[2])
        else:
            x = pose[0] + v / w * (np.sin(yaw) - math.sin(pose[2]))
            y = pose[1] - v / w * (np.cos(yaw) - math.cos(pose[2]))
        return np.stack([x, y], axis=-1)

    def _clearance_at(self, pts: np.ndarray) -> np.ndarray:
        cells = self.domain.geometry.world_to_cell(pts)
        inside = self.domain.geometry.contains_cell(cells)
        out = np.zeros(len(pts))
        out[inside] = self.clearance[cells[inside, 0], cells[inside, 1]]
        return out

    def _blocked(self, pose, v, w, neighbours, radii, scan_points) -> str:
        if abs(v) < 1e-9:
            return ""
        c = self.config
        arc = self._arc(np.asarray(pose, dtype=np.float64), v, w)
        clear = self._clearance_at(arc)
        # Into the inflated zone, and closer to the obstacle than now: a robot already too
        # close (pushed, or started there) may still move away.
        if np.any((clear[1:] < self.needed) & (clear[1:] < clear[0] - 1e-9)):
            return "wall ahead"
        p0 = arc[0]
        if neighbours is not None and len(neighbours):
            nb = np.asarray(neighbours, dtype=np.float64).reshape(-1, 2)
            r = np.broadcast_to(np.asarray(radii if radii is not None else c.radius,
                                           dtype=np.float64), (len(nb),))
            need = c.radius + r + c.robot_margin
            d_now = np.hypot(*(nb - p0).T)
            d_arc = np.hypot(arc[1:, None, 0] - nb[None, :, 0],
                             arc[1:, None, 1] - nb[None, :, 1]).min(axis=0)
            if np.any((d_arc < need) & (d_arc < d_now - 1e-6)):
                return "robot ahead"
        if scan_points is not None and len(scan_points):
            sp = np.asarray(scan_points, dtype=np.float64).reshape(-1, 2)
            reach = float(np.hypot(*(arc[-1] - p0))) + c.radius + 0.2
            near = sp[np.hypot(*(sp - p0).T) < reach]
            if len(near):
                d_arc = np.hypot(arc[1:, None, 0] - near[None, :, 0],
                                 arc[1:, None, 1] - near[None, :, 1]).min(axis=0)
                d_now = np.hypot(*(near - p0).T)
                if np.any((d_arc < c.radius + c.obstacle_margin) & (d_arc < d_now - 1e-6)):
                    return "obstacle in scan"
        return ""
