"""Bhattacharya, Michael, Kumar et al. (2014), *Multi-robot coverage and exploration on
Riemannian manifolds with boundary*: the paper's experiments (Sec. 4) beside its values.

* Fig. 13: the tessellation of a 200 x 200 grid with an L-shaped obstacle "after expansion of
  about 37300 vertices"; ours: the vertices one robot's decentralized update visits, counted in
  its search (:func:`.search_count.counting_searches`), in ``paper`` and in ``visibility`` mode.
* Figs. 15-16: coverage on the complete sphere (4 robots, the paper's 300 x 600 chart grid)
  and on a torus with two obstacles (5 robots): the converged configuration (a regular
  tetrahedron of equal cells on the sphere), iterations, H never rising.
* Figs. 18-19: 4 robots explore an unknown office of 284 x 333 cells; in Fig. 19 a person
  holds robot 0 in the larger room and footprints differ (power cells).

The seed draws the start: three agents anywhere on the L map, a start cluster anywhere on the
surface (the paper's robots "start off close to each other"), a start cluster in the office.
"""

from __future__ import annotations

import functools
import math
import statistics

import numpy as np

from coverage_ros.bench.papers import Experiment, Metric
from coverage_ros.bench.papers.search_count import counting_searches
from coverage_ros.core.geodesic.cell import SearchCache, geodesic_cell
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tessellation import Generator, tessellate
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError

PAPER = "Bhattacharya et al. 2014"

# ------------------------------------------------------------------ Fig. 13

FIG13_SIDE = 200  # [cells] the paper's 200 x 200 uniform discretization
FIG13_RES = 0.05  # [m] per cell (the counts do not depend on it)
#: [cells] the L's arms: 100 long and 14 thick block 2,604 cells, which leaves 37,396 free
#: vertices - the paper's complete diagram expanded "about 37300".
FIG13_ARM, FIG13_THICK = 100, 14
FIG13_AGENTS = 3  # "starting from three points (the location of the agents)"
FIG13_EXPANDED = 37300  # vertices the paper's complete tessellation expanded (caption)
FIG13_SEPARATION = 1.0  # [m] fewest distance between two agents (20 cells)
FIG13_ITERATIONS = 30  # team iterations whose updates are counted (a vertex per step)


@functools.lru_cache(maxsize=1)
def l_domain() -> CoverageDomain:
    """Fig. 13 re-drawn: an L-shaped obstacle in the middle of 200 x 200 free cells."""
    from coverage_ros.core.world.grid import OCCUPIED

    occ = np.zeros((FIG13_SIDE, FIG13_SIDE), dtype=np.int8)
    a = (FIG13_SIDE - FIG13_ARM) // 2  # the corner's row and column (rows grow with y)
    occ[a:a + FIG13_ARM, a:a + FIG13_THICK] = OCCUPIED  # upright arm
    occ[a:a + FIG13_THICK, a:a + FIG13_ARM] = OCCUPIED  # arm along the bottom
    return CoverageDomain.from_grid(GridMap(occ, FIG13_RES, (0.0, 0.0, 0.0)), 0.0)


def spread_points(domain: CoverageDomain, k: int, rng: np.random.Generator,
                  separation: float) -> np.ndarray:
    """``(k, 2)`` [m]: uniformly random free points, pairwise at least ``separation`` apart."""
    free = np.flatnonzero(domain.free.ravel())
    pts: list[np.ndarray] = []
    while len(pts) < k:
        p = domain.to_map(domain.node_centers(rng.choice(free, 1)))[0]
        if all(math.hypot(*(p - q)) >= separation for q in pts):
            pts.append(p)
    return np.array(pts)


def fig13_updates(domain: CoverageDomain, starts: np.ndarray, method: str,
                  iterations: int = FIG13_ITERATIONS) -> list[int]:
    """Vertices visited by every robot's update (each robot with its own search cache and
    nothing memoized from another robot's search, as on its own computer) over ``iterations``
    of the paper's control from ``starts``: every robot steps to its next vertex (l. 32)."""
    pos = np.array(starts, dtype=np.float64)
    caches = [SearchCache() for _ in pos]
    visits: list[int] = []
    for _ in range(iterations):
        goals = []
        for i in range(len(pos)):
            domain._cache.pop("shared_search", None)  # as alone: no other robot's search
            gens = [Generator(p) for p in pos]
            with counting_searches() as count:
                cell = geodesic_cell(domain, gens[i], gens[:i] + gens[i + 1:], cache=caches[i],
                                     method=method)
            visits.append(count.settled + count.sighted)
            goals.append(cell.next_vertex)
        pos = np.array(goals)
    return visits


def fig13(seed: int) -> dict[str, float]:
    """Fig. 13: three agents on the L map; the complete diagram (the paper's search), and each
    robot's decentralized updates as they step, in both modes."""
    domain = l_domain()
    starts = spread_points(domain, FIG13_AGENTS, np.random.default_rng(seed), FIG13_SEPARATION)
    with counting_searches() as count:
        tessellate(domain, [Generator(p) for p in starts], method="paper")
    out = {"vertices expanded, complete diagram (centralized)": float(count.settled)}
    for method in ("paper", "visibility"):
        visits = fig13_updates(domain, starts, method)
        out[f"vertices visited per update, {method} mode: median"] = statistics.median(visits)
        out[f"vertices visited per update, {method} mode: largest"] = float(max(visits))
    return out


# ------------------------------------------------------------------ Figs. 15-16

SPHERE_CELLS_PER_PI = 300  # the paper's 300 x 600 chart grid (Fig. 15)
SPHERE_ROBOTS = 4
TETRAHEDRON_ANGLE = math.degrees(math.acos(-1.0 / 3.0))  # [deg] 109.47, between two vertices
FIG15_ITERATIONS = 211  # Fig. 15(d), the converged solution, at t = 211
FIG15_RATE = 1.0  # [Hz] "the program ran (control computation as well as plotting) at ~1 Hz"
TORUS_CELLS = 200  # [cells] per angle; the paper does not give its torus grid
TORUS_ROBOTS = 5
TORUS_R, TORUS_TUBE = 2.0, 1.0  # axial and tube radius; the paper does not give them
#: Two obstacles in the chart (x0, y0, x1, y1) [rad] (the paper's are only a picture).
TORUS_OBSTACLES = ((0.6, 1.0, 1.4, 2.2), (3.0, 3.6, 4.2, 4.4))
FIG16_ITERATIONS = 276  # Fig. 16(d), the last frame, at t = 276
SURFACE_MAX_ITERATIONS = 400
CLUSTER_SPREAD_RAD = 0.1  # [rad] std of a start cluster about its centre
CLUSTER_GAP_RAD = 0.04  # [rad] fewest chart distance between two robots of a start cluster
SURFACE_TOLERANCE = 0.002  # [rad] converged: every goal within a fifth of a sphere cell


@functools.lru_cache(maxsize=2)
def surface(kind: str) -> CoverageDomain:
    """The sphere of Fig. 15 (``kind`` "sphere") or the torus of Fig. 16."""
    from coverage_ros.core.geodesic.charts import sphere_domain, torus_domain

    if kind == "sphere":
        return sphere_domain(SPHERE_CELLS_PER_PI)
    return torus_domain(TORUS_CELLS, TORUS_R, TORUS_TUBE, TORUS_OBSTACLES)


def surface_cluster(kind: str, k: int, seed: int) -> np.ndarray:
    """``(k, 2)`` chart positions: a start cluster about a centre drawn uniformly on the
    surface's area (on the sphere: colatitude by its area law, longitude uniform)."""
    from coverage_ros.core.geodesic.charts import wrap_chart_position

    domain = surface(kind)
    rng = np.random.default_rng(seed)
    while True:
        if kind == "sphere":
            centre = np.array([math.acos(1.0 - 2.0 * rng.uniform()), rng.uniform(0, 2 * math.pi)])
        else:
            centre = rng.uniform(0.0, 2.0 * math.pi, 2)
        if domain.is_free_point(centre):
            break
    pts: list[np.ndarray] = []
    for _ in range(10000):
        if len(pts) == k:
            return np.array(pts)
        d = rng.normal(0.0, CLUSTER_SPREAD_RAD, 2)
        if kind == "sphere":  # a longitude step spans sin(colatitude) of its length
            d[1] /= max(math.sin(centre[0]), 0.2)
        p = wrap_chart_position(domain, centre + d)
        if domain.is_free_point(p) and all(math.hypot(*(p - q)) >= CLUSTER_GAP_RAD for q in pts):
            pts.append(p)
    raise ConfigError.at("surface_cluster", f"no room for {k} robots", tuple(centre))


def surface_run(kind: str, k: int, seed: int):
    """The team's offline run from a start cluster (the robots' own updates, Jacobi steps)."""
    from coverage_ros.core.offline.runner import OfflineConfig, run_offline
    from coverage_ros.core.strategies import StrategyContext, strategy_choice

    domain = surface(kind)
    ctx = [StrategyContext(domain=domain, robot_id=i, convergence_tolerance=SURFACE_TOLERANCE)
           for i in range(k)]
    # the paper's generalized Lloyd, along which H never rises: without the moves priced by
    # the team's descent, whose relocation across the torus raises H while the robot drives
    choice = strategy_choice("geodesic", {"escape_descent_offers": 0}, "surface_run")
    return run_offline(domain, choice, surface_cluster(kind, k, seed), contexts=ctx,
                       config=OfflineConfig(max_iterations=SURFACE_MAX_ITERATIONS))


def fig15(seed: int) -> dict[str, float]:
    """Fig. 15: four robots from a start cluster on the complete sphere."""
    res = surface_run("sphere", SPHERE_ROBOTS, seed)
    th, ph = res.positions[-1].T
    xyz = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=1)
    angles = np.degrees(np.arccos(np.clip(xyz @ xyz.T, -1.0, 1.0)))[np.triu_indices(4, 1)]
    masses = tessellate(surface("sphere"), [Generator(p) for p in res.positions[-1]]).masses
    per_iteration = np.array(res.update_seconds).reshape(res.iterations, SPHERE_ROBOTS).sum(1)
    return {"converged (1 = yes)": float(res.converged),
            "iterations to converge": float(res.iterations),
            "angle between two robots farthest from the tetrahedron's":
                float(angles[np.argmax(np.abs(angles - TETRAHEDRON_ANGLE))]),
            "smallest / largest cell area": float(masses.min() / masses.max()),
            "team iterations per second (4 robots' updates)":
                1.0 / statistics.median(per_iteration.tolist())}


def fig16(seed: int) -> dict[str, float]:
    """Fig. 16: five robots from a start cluster on the torus with two obstacles."""
    res = surface_run("torus", TORUS_ROBOTS, seed)
    rises = np.diff(res.costs) > 1e-9 * res.costs[0]
    return {"converged (1 = yes)": float(res.converged),
            "iterations to converge": float(res.iterations),
            "iterations in which H rose": float(rises.sum())}


# ------------------------------------------------------------------ Figs. 18-19

OFFICE_RES = 0.05  # [m] per cell: 16.55 m x 14.1 m + a wall ring = 284 x 333 cells (paper)
OFFICE_SIZE = (16.55, 14.1)  # [m]
BIG_ROOM = (0.0, 0.0, 9.0, 5.5)  # [m] the larger room at the bottom (x0, y0, x1, y1), Fig. 19
#: Walls ((x0, y0), (x1, y1)) [m]: corridor walls with 1 m doors, then the rooms' walls.
OFFICE_WALLS = (((0, 5.5), (3.5, 5.5)), ((4.5, 5.5), (9.6, 5.5)), ((10.5, 5.5), (13.6, 5.5)),
                ((14.5, 5.5), (16.55, 5.5)), ((0, 7.3), (1.6, 7.3)), ((2.6, 7.3), (5.6, 7.3)),
                ((6.6, 7.3), (9.8, 7.3)), ((10.8, 7.3), (13.8, 7.3)), ((14.8, 7.3), (16.55, 7.3)),
                ((9.0, 0), (9.0, 5.5)), ((12.8, 0), (12.8, 5.5)), ((4.2, 7.3), (4.2, 14.1)),
                ((8.4, 7.3), (8.4, 14.1)), ((12.4, 7.3), (12.4, 14.1)))
#: Desks, a table, a pillar, a shelf, a corner unit.
OFFICE_FURNITURE = (
    {"type": "box", "center": [2.5, 2.0], "size": [2.0, 1.0]},
    {"type": "box", "center": [6.5, 2.8], "size": [1.2, 2.4], "yaw": 0.3},
    {"type": "circle", "center": [11.0, 2.5], "radius": 0.4},
    {"type": "box", "center": [2.0, 11.5], "size": [0.6, 2.0]},
    {"type": "box", "center": [10.4, 11.0], "size": [1.6, 0.8]},
    {"type": "polygon", "points": [[14.0, 12.5], [16.0, 12.5], [16.0, 13.8]]})
EXPLORE_ROBOTS = 4
EXPLORE_DURATION = 900.0  # [s] sim time at most (scripts/bench_explore's limit)
FIG18_ITERATIONS, FIG19_ITERATIONS = 1550, 2100  # converged solutions (Figs. 18(d), 19(d))
PAPER_RATE = 4.0  # [Hz] "about 3-4 Hz" (2.1 GHz processor): the top of the range
FOOTPRINTS = (2.0, 2.0, 1.0, 1.0)  # [m] Fig. 19's footprints = power weights; robot 0 held


@functools.lru_cache(maxsize=1)
def office():
    """A 284 x 333 office floor re-drawn after Figs. 18-19: a corridor, a larger room at the
    bottom beside two smaller ones, four rooms at the top, 1 m doors, some furniture."""
    from coverage_ros.core.world import parse_world

    walls = [{"type": "wall", "from": list(a), "to": list(b), "thickness": 0.1}
             for a, b in OFFICE_WALLS]
    return parse_world({"name": "office_284x333", "resolution": OFFICE_RES,
                        "bounds": [0.0, 0.0, *OFFICE_SIZE],
                        "obstacles": walls + [dict(f) for f in OFFICE_FURNITURE]})


def explore(seed: int, held: bool) -> dict[str, float]:
    """Fig. 18 (``held`` False: four robots from a start cluster anywhere) or Fig. 19 (all start
    in the larger room, robot 0 held there, footprints of two sizes): one offline exploration
    of the unknown office, to convergence."""
    from coverage_ros.core.offline.exploration import ExplorationConfig, run_exploration
    from coverage_ros.core.strategies import strategy_choice
    from coverage_ros.core.world import RobotSpec, cluster_starts
    from coverage_ros.core.world.grid import OCCUPIED

    world, config = office(), ExplorationConfig(duration=EXPLORE_DURATION)
    specs = ([RobotSpec(sensor_radius=r, power_weight=r) for r in FOOTPRINTS] if held
             else [world.robot_spec(i) for i in range(EXPLORE_ROBOTS)])
    radius, (x0, y0, x1, y1) = max(s.radius for s in specs), BIG_ROOM
    where = world.grid.occupancy.copy()
    if held:  # the start cluster in the larger room: the rest blocked for the draw
        X, Y = world.grid.all_cell_centers()
        where[(X < x0) | (X > x1) | (Y < y0) | (Y > y1)] = OCCUPIED
    starts = cluster_starts(world.grid.with_occupancy(where), len(specs), radius,
                            np.random.default_rng(seed))
    run = run_exploration(world.grid, strategy_choice("geodesic", explore=True), starts, specs,
                          config, held=[0] if held else [])
    out = {"explored share of the reachable free area": float(run.explored[-1]),
           "converged (1 = yes)": float(run.converged),
           "control iterations until converged": run.sim_time / config.control_period}
    if not held:
        n, u = len(specs), np.array(run.update_seconds)
        team = u[:len(u) // n * n].reshape(-1, n).sum(axis=1)  # every robot updates each period
        out["one robot's update rate"] = 1.0 / float(np.median(u))
        out["team's update rate (4 robots' updates, one process)"] = 1.0 / float(np.median(team))
        return out
    hx, hy = run.positions[:, 0].T
    out["held robot stayed in the larger room (1 = yes)"] = float(np.all(
        (x0 <= hx) & (hx <= x1) & (y0 <= hy) & (hy <= y1)))
    masses = tessellate(world_domain(world, radius),
                        [Generator(p, s.power_weight)
                         for p, s in zip(run.positions[-1], specs, strict=True)]).masses
    large = np.array(FOOTPRINTS) == max(FOOTPRINTS)
    out["smallest large-footprint cell / largest small-footprint cell"] = float(
        masses[large].min() / masses[~large].max())
    return out


# ------------------------------------------------------------------ the table's rows


def experiments() -> list[Experiment]:
    fig13_metrics = [Metric("vertices expanded, complete diagram (centralized)", FIG13_EXPANDED,
                            "close")]
    fig13_metrics += [Metric(f"vertices visited per update, {method} mode: {stat}",
                             FIG13_EXPANDED)
                      for method in ("paper", "visibility") for stat in ("median", "largest")]
    explored = Metric("explored share of the reachable free area", 1.0, "close")
    converged = Metric("converged (1 = yes)", 1.0, "higher")
    return [
        Experiment(
            PAPER, "Fig. 13", "L-shaped obstacle, 200 x 200 grid, 3 agents at random places",
            tuple(fig13_metrics), fig13, redrawn=True, key="bhattacharya2014/fig13",
            note="the paper counts its centralized search's expansions until the diagram is "
                 "complete (caption: 1, 10100, 25100, 30100, 37300); ours: the same search "
                 f"(first row), then every robot's own update (own search cache) over "
                 f"{FIG13_ITERATIONS} iterations of the paper's control (a vertex per step), "
                 "counted in the search: vertices Dijkstra settled, plus cells tested for line "
                 "of sight in visibility mode; the L (100 x 14-cell arms) leaves 37,396 free "
                 "vertices; agents 1 m apart at least"),
        Experiment(
            PAPER, "Fig. 15", "complete sphere, 300 x 600 chart grid, 4 robots from a cluster",
            (converged, Metric("iterations to converge", FIG15_ITERATIONS),
             Metric("angle between two robots farthest from the tetrahedron's",
                    round(TETRAHEDRON_ANGLE, 2), "close", "deg"),
             Metric("smallest / largest cell area", 1.0, "close"),
             Metric("team iterations per second (4 robots' updates)", FIG15_RATE, "higher",
                    "Hz")),
            fig15, key="bhattacharya2014/fig15",
            note="the paper shows the converged tetrahedron of equal cells as a picture (the "
                 "values are the regular tetrahedron's); its robots step one vertex per "
                 "iteration, ours to the cell's virtual centroid (monotone step rule, "
                 "tolerance 0.002 rad); its 1 Hz includes plotting, ours is the 4 updates"),
        Experiment(
            PAPER, "Fig. 16", "torus with two obstacles, 5 robots from a cluster",
            (converged, Metric("iterations to converge", FIG16_ITERATIONS),
             Metric("iterations in which H rose", 0.0)),
            fig16, redrawn=True, key="bhattacharya2014/fig16",
            note=f"R = {TORUS_R:g}, r = {TORUS_TUBE:g}, a {TORUS_CELLS} x {TORUS_CELLS} chart "
                 "grid and two rectangles in the chart: the paper gives none of them; its "
                 "robots step one vertex per iteration, ours to the virtual centroid"),
        Experiment(
            PAPER, "Fig. 18", "office 284 x 333 cells, 4 robots explore from a cluster",
            (explored, converged, Metric("control iterations until converged", FIG18_ITERATIONS),
             Metric("one robot's update rate", PAPER_RATE, "higher", "Hz"),
             Metric("team's update rate (4 robots' updates, one process)", PAPER_RATE,
                    "higher", "Hz")),
            functools.partial(explore, held=False), redrawn=True, slow=True,
            key="bhattacharya2014/fig18",
            note="an office re-drawn at the paper's 284 x 333 cells (5 cm; the Levine floor is "
                 "a picture); TurtleBot3s, 3.5 m lidars, 2 Hz control, one shared belief; "
                 "iterations = sim time / 0.5 s; the paper's 3-4 Hz is its whole program (one "
                 "pass computes every robot's control, 2.1 GHz), ours a robot's update (belief "
                 "domain, cell, control) timed on a shared 2-core machine: noisy"),
        Experiment(
            PAPER, "Fig. 19", "office 284 x 333 cells, robot 0 held in the larger room, "
            "footprints 2 m / 1 m",
            (explored, converged, Metric("control iterations until converged", FIG19_ITERATIONS),
             Metric("held robot stayed in the larger room (1 = yes)", 1.0, "higher"),
             Metric("smallest large-footprint cell / largest small-footprint cell", 1.0,
                    "higher")),
            functools.partial(explore, held=True), redrawn=True, slow=True,
            key="bhattacharya2014/fig19",
            note="all four start in the larger room, robot 0 held at its start throughout (the "
                 "paper's person drives it in the room); footprints are power weights (lidars "
                 "alike); the last row's 1 is the paper's claim (larger footprints hold larger "
                 "cells), for the power cells of the final positions on the true map"),
    ]
