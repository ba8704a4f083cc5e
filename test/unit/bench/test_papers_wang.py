"""Wang et al. 2024, Table I and Sec. V-A in ``scripts/bench_papers``: the two baselines
(OAVC's tangent lines, the adaptive method's repulsive density), their Lloyd step, and a small
Table I comparison on the benchmark's own scenarios."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import coverage_ros.bench.papers.wang2024 as wang
from coverage_ros.bench.peak_trials import (
    TrialOutcome,
    coverage_ratio,
    run_trial,
    success_rate,
    world_clearance,
)
from coverage_ros.core.baselines import (
    AdaptiveParams,
    AdaptiveStrategy,
    Circles,
    LloydParams,
    OavcStrategy,
)
from coverage_ros.core.baselines.adaptive import repulsive_weight
from coverage_ros.core.baselines.oavc import oavc_cell, tangent_halfplanes
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.strategies import Neighbour, Observation, SharedState, StrategyContext
from coverage_ros.core.world import parse_world
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.errors import ConfigError

R = 0.05  # [m] the benchmark's robot radius
TOL = 1e-9


# ---------------------------------------------------------------------------- OAVC geometry
@given(cx=st.floats(-5, 5), cy=st.floats(-5, 5), radius=st.floats(0.1, 2.0),
       angle=st.floats(-math.pi, math.pi), gap=st.floats(0.01, 5.0))
def test_a_tangent_line_touches_its_circle_nearest_the_robot_and_separates_them(
        cx, cy, radius, angle, gap):
    c = np.array([cx, cy])
    p = c + (radius + gap) * np.array([math.cos(angle), math.sin(angle)])
    plane = tangent_halfplanes(p, Circles(c[None], np.array([radius])), R)
    a, b = plane.a[0], plane.b[0]
    t = c - radius * a  # the tangent point
    assert np.hypot(*a) == pytest.approx(1.0)
    assert np.hypot(*(t - c)) == pytest.approx(radius)  # on the circle ...
    assert abs(a @ t - b) < 1e-9  # ... and on the line,
    assert np.hypot(*(p - t)) == pytest.approx(gap)  # the circle's point nearest the robot
    assert a @ c - radius == pytest.approx(b)  # the whole disc on the far side, touching at t
    assert a @ p < b  # the robot on the near side
    # The buffered side keeps a body of radius R clear of the disc.
    u = np.array([-a[1], a[0]])
    line = (b - plane.beta[0]) * a + np.linspace(-20, 20, 401)[:, None] * u
    assert np.hypot(*(line - c).T).min() >= radius + R - 1e-9


def _scenario_cells(k: int) -> tuple[Circles, np.ndarray, tuple]:
    setup = wang.scenario(k, robots=6)
    return Circles.from_world(setup.world), setup.starts[:, :2], setup.world.bounds


def _edge_points(poly: np.ndarray, per_edge: int = 60) -> np.ndarray:
    s = np.linspace(0.0, 1.0, per_edge, endpoint=False)[:, None, None]
    return (poly[None] + s * (np.roll(poly, -1, axis=0) - poly)[None]).reshape(-1, 2)


@pytest.mark.parametrize("k", [0, 1, 2])
def test_oavc_cells_keep_every_body_clear_of_circles_walls_and_each_other(k):
    circles, starts, bounds = _scenario_cells(k)
    cells = [oavc_cell(p, np.delete(starts, i, axis=0), circles, R, bounds)
             for i, p in enumerate(starts)]
    xmin, ymin, xmax, ymax = bounds
    for cell, p in zip(cells, starts, strict=True):
        assert len(cell.polygon) >= 3 and cell.buffer == R
        pts = _edge_points(cell.polygon)
        assert circles.gaps(pts).min() >= R - 1e-9
        assert min((pts[:, 0] - xmin).min(), (xmax - pts[:, 0]).min(),
                   (pts[:, 1] - ymin).min(), (ymax - pts[:, 1]).min()) >= R - 1e-9
        assert circles.gaps(p[None]).min() > R  # the robot stands in its own cell's range
        assert len(cell.obstacles) > 0  # the clutter does cut the cells
    for i in range(len(cells)):
        for j in range(i + 1, len(cells)):
            a, b = _edge_points(cells[i].polygon), _edge_points(cells[j].polygon)
            gap = np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1]).min()
            assert gap >= 2 * R - 1e-6


def test_oavc_knows_every_obstacle_and_the_adaptive_method_only_those_it_senses():
    """Global sensing (OAVC) vs local (adaptive, Wang et al. Table I): a circle 6 m ahead cuts
    OAVC's cell at its buffered tangent line; the adaptive robot (3 m sensor) ignores it."""
    domain, _ = _open_domain()
    far = Circles(np.array([[8.0, 4.0]]), np.array([1.0]))
    cell = oavc_cell(np.array([2.0, 4.0]), np.zeros((0, 2)), far, R, (0.0, 0.0, 10.0, 8.0))
    assert cell.polygon[:, 0].max() == pytest.approx(7.0 - R)
    assert cell.obstacles.tolist() == [0]
    ctx = StrategyContext(domain=domain, robot=RobotSpec(radius=R, sensor_radius=3.0))
    sensing = AdaptiveStrategy(ctx, None, far, (0.0, 0.0, 10.0, 8.0))
    assert len(sensing.detected(np.array([2.0, 4.0]))) == 0
    assert len(sensing.detected(np.array([4.5, 4.0]))) == 1  # 2.5 m from its boundary


# ---------------------------------------------------------------------------- adaptive density
def test_the_repulsive_density_is_the_one_defined():
    """phi_total = phi (1 - sum_k exp(-g_k^2 / (2 sigma^2)))^+ with g_k the distance to circle
    k's boundary (zero inside): the module's stated definition."""
    one = Circles(np.array([[0.0, 0.0]]), np.array([1.0]))
    sigma = 0.5
    g = np.array([0.0, 0.1, 0.5, 1.0, 3.0])
    pts = np.column_stack([1.0 + g, np.zeros_like(g)])
    assert np.allclose(repulsive_weight(pts, one, sigma), 1.0 - np.exp(-g ** 2 / (2 * sigma ** 2)))
    assert repulsive_weight(np.array([[0.3, 0.2]]), one, sigma)[0] == 0.0  # inside
    assert repulsive_weight(np.array([[40.0, 0.0]]), one, sigma)[0] == pytest.approx(1.0)
    two = Circles(np.array([[0.0, 0.0], [3.0, 0.0]]), np.array([1.0, 1.0]))
    mid = np.array([[1.5, 0.0]])  # 0.5 m from both: the two fields add (and clip at zero)
    assert repulsive_weight(mid, two, sigma)[0] == pytest.approx(max(1 - 2 * math.exp(-0.5), 0))
    assert repulsive_weight(mid, two, 1.0)[0] == 0.0
    assert np.all(repulsive_weight(pts, Circles(np.zeros((0, 2)), np.zeros(0)), sigma) == 1.0)


def test_the_repulsion_moves_the_centroid_away_from_a_detected_obstacle():
    domain, _ = _open_domain()
    beside = Circles(np.array([[6.0, 2.9]]), np.array([0.4]))  # just below the peak
    none = Circles(np.zeros((0, 2)), np.zeros(0))
    spec = RobotSpec(radius=R, sensor_radius=3.0)
    obs = Observation(0, np.array([5.0, 4.2, 0.0]), 0.0)
    goals = {}
    for label, circles in (("repelled", beside), ("plain", none)):
        ctx = StrategyContext(domain=domain, robot=spec)
        goals[label] = AdaptiveStrategy(ctx, None, circles, (0.0, 0.0, 10.0, 8.0)).update(
            obs, []).target
    gap = beside.gaps(np.array([goals["repelled"], goals["plain"]]))[:, 0]
    assert gap[0] > gap[1] + 0.05


# ---------------------------------------------------------------------------- the Lloyd step
def _open_domain(peak=(6.0, 4.0), sigma=0.6) -> tuple[CoverageDomain, object]:
    spec = parse_world({"name": "open", "resolution": 0.05, "bounds": [0, 0, 10, 8],
                        "density": {"type": "gaussian_mixture",
                                    "components": [{"mean": list(peak), "sigma": sigma}]}})
    return CoverageDomain.from_grid(spec.grid, R, spec.density), spec


@pytest.mark.parametrize("name", ["oavc", "adaptive"])
def test_a_lone_robot_without_obstacles_goes_to_the_density_centroid(name):
    domain, spec = _open_domain()
    robot = RobotSpec(radius=R, v_max=0.5, sensor_radius=3.0)
    none = Circles.from_world(spec)
    cls = OavcStrategy if name == "oavc" else AdaptiveStrategy
    params = LloydParams(period=0.2) if name == "oavc" else AdaptiveParams(period=0.2)

    def make(ctx):
        return cls(ctx, params, none, spec.bounds)

    start = np.array([3.5, 4.6])
    ctx = StrategyContext(domain=domain, robot=robot)
    first = make(ctx).update(Observation(0, np.array([*start, 0.0]), 0.0), [])
    # The centroid of the density over what the robot's cell holds: the whole arena (OAVC) or
    # the sensing disc, computed here from scratch.
    H, W = domain.shape
    xy = domain.to_map(domain.node_centers(np.arange(H * W)))
    w = domain.mass_element.ravel().copy()
    if name == "adaptive":
        w[np.hypot(*(xy - start).T) > 3.0] = 0.0
    want = (xy * w[:, None]).sum(axis=0) / w.sum()
    assert np.hypot(*(first.target - want)) < (1e-6 if name == "oavc" else 0.02)
    assert first.mode == "lloyd" and not first.converged
    out = run_trial(domain, world_clearance(spec), np.array([[*start, 0.0]]),
                    np.array([[6.0, 4.0]]), [ctx], strategy=make, dt=0.2, time_limit=20.0,
                    detect_radius=0.01, arrive_radius=0.1, stop_when_detected=False)
    assert out.converged and not out.collided
    assert np.hypot(*(out.positions[-1, 0] - [6.0, 4.0])) < 0.02  # the peak: the centroid
    assert len(out.update_times) == len(out.positions) - 1 and np.all(out.update_times > 0)


def test_a_two_cycle_on_the_raster_counts_as_converged():
    """The raster centroid is a step function of the position: a robot alternating between
    two points a cell apart moves at 0.5 m/s each period but its mean speed over two periods
    is zero (module docstring of ``common``); a robot creeping on is not converged."""
    domain, spec = _open_domain()
    ctx = StrategyContext(domain=domain, robot=RobotSpec(radius=R, v_max=0.5))
    robot = OavcStrategy(ctx, LloydParams(period=0.1, converged_speed=0.002),
                         Circles.from_world(spec), spec.bounds)
    square = np.array([[4.0, 3.0], [6.0, 3.0], [6.0, 5.0], [4.0, 5.0]])

    def mass_at(point):  # all the weight on the raster node at ``point``
        return lambda nodes, xy: (np.hypot(*(xy - point).T) < 0.03).astype(float)

    a, b, c = np.array([5.025, 4.025]), np.array([5.075, 4.025]), np.array([5.125, 4.025])
    there = robot.decide(a, 0.1, square, mass_at(b), "lloyd", 0)
    assert np.allclose(there.target, b) and not there.converged  # 0.5 m/s
    back = robot.decide(b, 0.1, square, mass_at(a), "lloyd", 0)
    assert np.allclose(back.target, a) and back.details.speed == pytest.approx(0.5)
    assert back.converged  # A -> B -> A: no net motion
    on = robot.decide(a, 0.1, square, mass_at(b), "lloyd", 0)
    on = robot.decide(b, 0.1, square, mass_at(c), "lloyd", 0)
    assert not on.converged  # A -> B -> C: 0.5 m/s on average


def test_settings_and_inputs_are_checked():
    with pytest.raises(ConfigError, match="u_max"):
        LloydParams(u_max=0.0)
    with pytest.raises(ConfigError, match="converged_speed"):
        LloydParams(converged_speed=math.nan)
    with pytest.raises(ConfigError, match="repulsion_sigma"):
        AdaptiveParams(repulsion_sigma=-1.0)
    with pytest.raises(ConfigError, match="radii"):
        Circles(np.zeros((1, 2)), np.array([0.0]))
    with pytest.raises(ConfigError, match="one radius per centre"):
        Circles(np.zeros((2, 2)), np.array([1.0]))
    boxes = parse_world({"name": "b", "resolution": 0.1, "bounds": [0, 0, 5, 5], "obstacles": [
        {"type": "box", "center": [2, 2], "size": [1, 1]}]})
    with pytest.raises(ConfigError, match="must all be circles"):
        Circles.from_world(boxes)
    domain, spec = _open_domain()
    ctx = StrategyContext(domain=domain)
    with pytest.raises(ConfigError, match="settings of the wrong kind"):
        AdaptiveStrategy(ctx, LloydParams(), Circles.from_world(spec))
    with pytest.raises(ConfigError, match="must be Circles"):
        OavcStrategy(ctx, None, [(1.0, 1.0, 0.5)])  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="method: unknown"):
        wang.method("voronoi", wang.scenario(0))


# ---------------------------------------------------------------------------- the benchmark
def _fake_outcome(n: int, collided: bool = False) -> TrialOutcome:
    return TrialOutcome(np.array([1.0, np.inf, 2.0]), collided, True, True, 12.0, 0.1, 0.3,
                        np.zeros((2, n, 2)), np.full(5, 0.01 * n))


@pytest.mark.parametrize("k", range(3))
def test_scaling_starts_keep_the_papers_margin_from_obstacles_and_each_other(k):
    """With ``margin`` the starts are that far from every obstacle and from each other's
    bodies - the team's minimum distance then measures the method, not the draw."""
    margin = wang.MIN_DISTANCE_PAPER * R
    size, count = wang.SCALING_WORLDS["28 m arena, dense"]
    setup = wang.scenario(10_000 * 16 + k, 16, count, size, margin=margin)
    starts = setup.starts[:, :2]
    assert world_clearance(setup.world)(starts).min() >= margin
    gaps = np.hypot(*(starts[:, None] - starts[None]).transpose(2, 0, 1))
    assert gaps[~np.eye(16, dtype=bool)].min() - R >= margin
    plain = wang.scenario(k).starts[:, :2]  # Table I's draw is unchanged
    assert world_clearance(wang.scenario(k).world)(plain).min() >= wang.START_CLEARANCE


def test_every_metric_of_the_experiments_is_what_a_run_returns(monkeypatch):
    """A run's keys are the metrics' names (a typo would leave a row without values)."""
    monkeypatch.setattr(wang, "scenario",
                        lambda k, robots=3, obstacles=0, size=0.0, margin=None: robots)
    monkeypatch.setattr(wang, "trial", lambda name, n, **kw: _fake_outcome(n))
    table, scaling = wang.experiments()
    assert table.key == "wang2024/table1" and table.redrawn and table.seeds >= 5
    for exp in (table, scaling):
        values = exp.run(0)
        assert sorted(values) == sorted(m.name for m in exp.metrics)
        assert all(math.isfinite(v) for v in values.values())
    paper = {m.name: m.paper_value for m in table.metrics}
    assert paper["success rate, Ours"] == 96.67 and paper["average time, OAVC"] == 17.14
    assert paper["coverage ratio, Adaptive"] == pytest.approx(13 / 30)
    values = scaling.run(0)
    assert values["update time, 16 / 2 robots, 16 m arena"] == pytest.approx(8.0)
    assert values["min distance / radius, 16 robots, 28 m arena, dense"] == pytest.approx(
        (0.1 + R) / R)


@pytest.mark.slow
def test_table_one_in_small_bvc_ahead_of_oavc_ahead_of_adaptive():
    """The benchmark's first three Table I scenarios at 0.2 s steps (the benchmark: 0.1 s, 30
    scenarios): the paper's order of success rates (96.67 % > 46.67 % > 10 %), bvc and OAVC
    without a collision (their cells keep every body clear), bvc finding as many peaks."""
    runs = {name: [wang.trial(name, wang.scenario(k), dt=0.2) for k in range(3)]
            for name in ("bvc", "oavc", "adaptive")}
    rate = {name: success_rate(out) for name, out in runs.items()}
    print(rate, {name: coverage_ratio(out) for name, out in runs.items()})
    assert rate["bvc"] >= 2 / 3
    assert rate["bvc"] > rate["oavc"] > rate["adaptive"]
    assert not any(o.collided for o in runs["bvc"] + runs["oavc"])
    assert coverage_ratio(runs["bvc"]) >= max(coverage_ratio(runs["oavc"]),
                                              coverage_ratio(runs["adaptive"]))
    assert all(o.duration <= wang.TIME_LIMIT for o in runs["bvc"])


def test_neighbours_bisectors_bound_the_baselines_cells():
    domain, spec = _open_domain()
    ctx = StrategyContext(domain=domain, robot=RobotSpec(radius=R, sensor_radius=3.0))
    other = Neighbour(1, SharedState(position=np.array([6.0, 4.0])))
    for cls in (OavcStrategy, AdaptiveStrategy):
        d = cls(ctx, None, Circles.from_world(spec), spec.bounds).update(
            Observation(0, np.array([5.0, 4.0, 0.0]), 0.0), [other])
        assert d.cell_polygon[:, 0].max() <= 5.5 - R + TOL  # bisector x = 5.5, buffered
        assert d.target[0] < 5.5 - R + TOL  # the peak is the neighbour's: wait at the border
