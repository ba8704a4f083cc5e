"""bvc's peaks that no robot attends (coverage_ros.core.strategies.bvc.peaks): which cells are
peaks, who keeps a peak, the matching of the others to the open ones, and a robot left beside
its neighbour at a shared peak heading for the open one."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from conftest import WORLDS

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.offline.rangesim import simulate_scan
from coverage_ros.core.strategies import (
    Neighbour,
    Observation,
    SharedState,
    StrategyContext,
    make_strategy,
    strategy_choice,
)
from coverage_ros.core.strategies.bvc.guided_map import local_map, without_discs
from coverage_ros.core.strategies.bvc.memory import ObstacleMemory
from coverage_ros.core.strategies.bvc.peaks import density_peaks, peak_role
from coverage_ros.core.world import LidarSpec, RobotSpec, load_world, parse_world
from coverage_ros.errors import ConfigError

TWO_PEAKS = np.array([[2.0, 3.0], [10.0, 3.0]])


def _domain(components: list[dict] | None, floor: float = 0.0) -> CoverageDomain:
    density = {"type": "uniform"} if components is None else {
        "type": "gaussian_mixture", "floor": floor, "components": components}
    spec = parse_world({"name": "open", "resolution": 0.1, "bounds": [0, 0, 12, 6],
                        "density": density})
    return CoverageDomain.from_grid(spec.grid, 0.105, spec.density)


def _two_peak_domain() -> CoverageDomain:
    return _domain([{"mean": list(p), "sigma": 0.7} for p in TWO_PEAKS])


def test_the_peaks_are_the_tops_of_the_bumps_and_a_flat_map_has_none():
    found = density_peaks(_two_peak_domain(), 3.0)
    assert len(found) == 2
    assert np.abs(np.sort(found, axis=0) - TWO_PEAKS).max() <= 0.1  # within a cell
    assert len(density_peaks(_domain(None), 3.0)) == 0
    # The field world's two areas of interest, on a floor of 0.05, with obstacles.
    spec = load_world(WORLDS / "field.yaml")
    field = CoverageDomain.from_grid(spec.grid, spec.robot.radius, spec.density)
    found = density_peaks(field, 3.5)
    assert len(found) == 2
    assert np.abs(found[np.argsort(found[:, 0])] - [[4.0, 9.5], [13.0, 6.0]]).max() <= 0.05
    # A second bump below PEAK_SHARE of the first is a ripple, not a peak.
    faint = _domain([{"mean": [2.0, 3.0], "sigma": 0.7, "weight": 1.0},
                     {"mean": [10.0, 3.0], "sigma": 0.7, "weight": 0.01}])
    assert len(density_peaks(faint, 3.0)) == 1


def test_the_owner_keeps_its_peak_and_the_robot_beside_it_takes_the_open_one():
    owner, beside = np.array([2.2, 3.0]), np.array([1.6, 3.0])
    role = peak_role(owner, TWO_PEAKS, beside[None], 3.0)
    assert role.owns and role.target is None and not role.peakless
    role = peak_role(beside, TWO_PEAKS, owner[None], 3.0)
    assert not role.owns and np.array_equal(role.target, TWO_PEAKS[1])
    # Both peaks attended: the robot beside an owner owns none and seeks none.
    third = np.array([9.0, 3.0])
    assert peak_role(beside, TWO_PEAKS, np.array([owner, third]), 3.0).peakless
    # One open peak, two robots without one: the nearer goes, the other covers.
    far = np.array([1.0, 5.0])
    assert np.array_equal(peak_role(beside, TWO_PEAKS, np.array([owner, far]), 3.0).target,
                          TWO_PEAKS[1])
    assert peak_role(far, TWO_PEAKS, np.array([owner, beside]), 3.0).peakless


def test_the_matching_does_not_leave_a_far_robot_the_farthest_peak():
    # Table I's scenario 4 (rounded): greedy pairing, the closest pair first, sends robot 1
    # to peak 1 (4.5 m) and leaves robot 0 peak 0, 15.4 m away; the least total distance sends
    # robot 1 to peak 0 (6.8 m) and robot 0 to peak 1 (7.7 m).
    peaks = np.array([[12.5, 2.5], [6.2, 7.2], [4.7, 1.5]])
    team = np.array([[1.8, 13.6], [10.3, 8.9], [1.1, 2.5]])
    got = [_target(team, i, peaks, 3.0) for i in range(3)]
    assert np.array_equal(got[0], peaks[1]) and np.array_equal(got[1], peaks[0])
    assert np.array_equal(got[2], peaks[2])


def _target(team: np.ndarray, i: int, peaks: np.ndarray, reach: float) -> np.ndarray | None:
    return peak_role(team[i], peaks, np.delete(team, i, axis=0), reach).target


@pytest.mark.parametrize("seed", range(5))
def test_every_robot_computes_the_same_matching(seed):
    rng = np.random.default_rng(seed)
    peaks, team = rng.uniform(0, 20, (4, 2)), rng.uniform(0, 20, (6, 2))
    got = [_target(team, i, peaks, 2.0) for i in range(6)]
    chosen = [tuple(g) for g in got if g is not None]
    assert len(chosen) == len(set(chosen))  # no open peak sent two robots
    d = np.hypot(*(peaks[:, None] - team[None]).transpose(2, 0, 1))
    owner = d.argmin(axis=1)
    attended = d[np.arange(4), owner] <= 2.0
    open_peaks = [k for k in range(4) if not attended[k]]
    assert len(chosen) == min(len(open_peaks), 6 - len(set(owner[attended])))
    # The least total distance: no other assignment of the same robots does better.
    movers = [i for i in range(6) if got[i] is not None]
    cost = sum(np.hypot(*(got[i] - team[i])) for i in movers)
    for perm in itertools.permutations(open_peaks, len(movers)):
        alt = sum(np.hypot(*(peaks[k] - team[i])) for i, k in zip(movers, perm, strict=True))
        assert cost <= alt + 1e-9


def _update(robot, position: np.ndarray, other: np.ndarray, t: float):
    pose = np.array([*position, 0.0])
    scan = simulate_scan(robot.context.domain.geometry, pose, LidarSpec(range_max=3.5),
                         other[None], np.array([0.105]))
    return robot.update(Observation(0, pose, t, scan), [Neighbour(1, SharedState(other))])


def test_a_robot_beside_its_neighbour_at_a_shared_peak_heads_for_the_open_one():
    domain = _two_peak_domain()
    ctx = StrategyContext(domain=domain, robot=RobotSpec(sensor_radius=3.5,
                                                         lidar=LidarSpec(range_max=3.5)))
    owner, beside = np.array([2.2, 3.0]), np.array([1.6, 3.0])
    seeking = make_strategy("bvc", ctx)
    d = _update(seeking, beside, owner, 0.0)
    assert d.details.guide_goal[0] > 4.5  # towards peak 1, at the edge of its range
    assert d.target[1] == pytest.approx(3.0, abs=0.3)
    staying = make_strategy(strategy_choice("bvc", {"seek_peaks": False}), ctx)
    d = _update(staying, beside, owner, 0.0)
    assert d.details.guide_goal[0] < 2.0  # the shared peak's side of its bisector


def test_seek_peaks_must_be_a_flag():
    ctx = StrategyContext(domain=_two_peak_domain())
    with pytest.raises(ConfigError, match=r"bvc\.seek_peaks"):
        make_strategy(strategy_choice("bvc", {"seek_peaks": "yes"}), ctx)


def test_a_plateau_is_not_a_peak():
    spec = parse_world({"name": "rooms", "resolution": 0.1, "bounds": [0, 0, 12, 6],
                        "density": {"type": "targets", "value": 5.0, "outside": 1.0,
                                    "polygons": [[[1, 1], [4, 1], [4, 4], [1, 4]]]}})
    domain = CoverageDomain.from_grid(spec.grid, 0.105, spec.density)
    assert len(density_peaks(domain, 3.0)) == 0


@pytest.mark.parametrize("seed", range(3))
def test_teammates_block_the_cells_within_their_discs_as_a_whole_window_check_does(seed):
    rng = np.random.default_rng(seed)
    memory = ObstacleMemory.covering((0.0, 0.0, 16.0, 16.0), 0.1)
    memory.add(rng.uniform(0, 16, (300, 2)))
    local = local_map(memory, np.array([8.0, 8.0]), 60, 0.05)
    centres = rng.uniform(-1, 17, (15, 2))  # some off the window, some off the map
    radii = rng.uniform(0.1, 0.5, 15)
    h, w = local.free.shape
    rows, cols = np.mgrid[0:h, 0:w]
    xy = memory.centers((rows + local.row0).ravel(), (cols + local.col0).ravel())
    d = np.hypot(xy[:, None, 0] - centres[None, :, 0], xy[:, None, 1] - centres[None, :, 1])
    near = np.any(d <= radii[None, :] + 0.05, axis=1).reshape(h, w)
    blocked = without_discs(local, centres, radii)
    assert np.array_equal(blocked.free, local.free & ~near)
    assert not (blocked.reachable & ~blocked.free).any()
    assert np.array_equal(without_discs(local, np.zeros((0, 2)), np.zeros(0)).free, local.free)


def test_a_robot_without_a_peak_to_keep_or_seek_covers_round_the_owner():
    # Both peaks attended (an owner at each): the robot beside the first owner moves to the
    # centroid of its cell under the importance density (Lloyd), not up against the owner.
    domain = _two_peak_domain()
    ctx = StrategyContext(domain=domain, robot=RobotSpec(sensor_radius=3.5,
                                                         lidar=LidarSpec(range_max=3.5)))
    owner, beside, other = np.array([2.2, 3.0]), np.array([1.6, 3.0]), np.array([10.0, 3.0])
    pose = np.array([*beside, 0.0])
    scan = simulate_scan(domain.geometry, pose, LidarSpec(range_max=3.5),
                         np.array([owner, other]), np.array([0.105, 0.105]))
    nbrs = [Neighbour(1, SharedState(owner)), Neighbour(2, SharedState(other))]
    d = make_strategy("bvc", ctx).update(Observation(0, pose, 0.0, scan), nbrs)
    assert d.mode == "plain" and d.details.guide_goal is None
    # The density-weighted centroid of its cell: left of the bisector (x = 1.9), by the peak.
    cell_nodes = d.cell
    xy = domain.to_map(domain.node_centers(cell_nodes))
    w = domain.mass_element.ravel()[cell_nodes]
    assert np.allclose(d.target, (xy * w[:, None]).sum(axis=0) / w.sum(), atol=1e-9)
    staying = make_strategy(strategy_choice("bvc", {"seek_peaks": False}), ctx)
    d = staying.update(Observation(0, pose, 0.0, scan), nbrs)
    assert d.mode == "guided" and d.details.guide_goal[0] > 1.7  # at the bisector, by the owner
