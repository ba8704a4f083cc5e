"""bvc under a flat density: the guide is the middle of what the robot's scans have seen free of
its own region, not only what the current scan sees - a pillar that hides part of the region
now must not pull the guide off-centre (the live sandbox team then settled with one side thin)."""

from __future__ import annotations

import numpy as np

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.offline.rangesim import simulate_scan
from coverage_ros.core.strategies import Observation, StrategyContext, make_strategy
from coverage_ros.core.strategies.bvc.guided_map import ObstacleMemory
from coverage_ros.core.world.grid import OCCUPIED, GridMap
from coverage_ros.core.world.robot import RobotSpec

RES = 0.05  # [m]


def test_the_memory_accumulates_what_scans_saw_free_within_reach():
    memory = ObstacleMemory.covering((0.0, 0.0, 4.0, 4.0), 0.1)
    left = memory.centers(np.array([20]), np.array([5]))  # (0.55, 2.05)
    right = memory.centers(np.array([20]), np.array([35]))  # (3.55, 2.05)
    assert not memory.was_seen(np.vstack([left, right])).any()  # nothing seen yet
    memory.add_view(np.array([2.0, 2.0]), 1.0, lambda q: q[:, 0] < 2.0)  # sees west only
    assert memory.was_seen(np.array([[1.55, 2.05], [2.45, 2.05]])).tolist() == [True, False]
    assert not memory.was_seen(left).any()  # 1.45 m away: beyond the reach
    memory.add_view(np.array([2.0, 2.0]), 2.0, lambda q: q[:, 0] > 2.0)  # then east, farther
    assert memory.was_seen(np.array([[1.55, 2.05], [3.55, 2.05]])).tolist() == [True, True]
    assert memory.was_seen(np.array([[-3.0, 2.0], [9.0, 9.0]])).tolist() == [False, False]
    memory.add_view(np.array([50.0, 50.0]), 1.0, lambda q: np.ones(len(q), bool))  # off-grid


def _room_with_pillar() -> CoverageDomain:
    """A 6 x 4 m room with a 0.6 m square pillar in the middle of its east half."""
    occ = np.zeros((80, 120), np.int8)
    occ[:2], occ[-2:], occ[:, :2], occ[:, -2:] = OCCUPIED, OCCUPIED, OCCUPIED, OCCUPIED
    occ[34:46, 84:96] = OCCUPIED  # x 4.2-4.8 m, y 1.7-2.3 m
    return CoverageDomain.from_grid(GridMap(occ, RES), 0.105)


def test_a_pillar_that_hides_part_of_the_region_now_does_not_move_the_guide():
    domain = _room_with_pillar()
    spec = RobotSpec(sensor_radius=3.5)
    ctx = StrategyContext(domain=domain, robot=spec, robot_id=0)
    grid = domain.geometry
    east = np.array([5.5, 2.0, 0.0])  # sees the whole east end
    west = np.array([3.6, 2.0, 0.0])  # the pillar hides the strip behind it (x > 4.8)

    def guide(robot, pose, t):
        scan = simulate_scan(grid, pose, spec.lidar)
        return robot.update(Observation(0, pose, t, scan), []).details.guide_goal

    fresh = make_strategy("bvc", ctx)
    only_now = guide(fresh, west, 0.0)
    travelled = make_strategy("bvc", ctx)
    guide(travelled, east, 0.0)
    remembered = guide(travelled, west, 0.2)
    # Within 3.5 m of x = 3.6 the room spans x 0.1..5.9; what the pillar hides lies east, so
    # the guide from the current scan alone sits west of the one from everything seen.
    assert remembered[0] > only_now[0] + 0.05, (only_now, remembered)
