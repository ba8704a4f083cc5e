"""A domain cut down to the window of its free space (coverage_ros.core.geodesic.crop) computes
as the whole domain does: the same tessellation bit for bit, and the geodesic team step on the
window gives the whole domain's cells, sums and goals."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_points, shared_map

from coverage_ros.core.geodesic.charts import sphere_domain, torus_domain
from coverage_ros.core.geodesic.crop import cropped, free_window, window_of
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tangents import SIGHT_TILE
from coverage_ros.core.geodesic.tessellation import Generator, fast_tessellate, tessellate
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.offline.geodesic_team import team_cells
from coverage_ros.core.offline.lloyd_team import GeodesicTeam
from coverage_ros.core.world import load_world
from coverage_ros.core.world.grid import OCCUPIED, GridMap

UNKNOWN = -1


def _slam_like(yaw: float = 0.0) -> CoverageDomain:
    """Two rooms and a doorway in the middle of a wide unknown margin, as a SLAM map has."""
    occ = np.full((220, 260), UNKNOWN, dtype=np.int8)
    occ[70:141, 90:201] = OCCUPIED
    occ[71:140, 91:200] = 0
    occ[71:140, 145:148] = OCCUPIED  # the wall between the rooms
    occ[100:112, 145:148] = 0  # its doorway
    occ[80:90, 110:118] = OCCUPIED  # a pillar
    return CoverageDomain.from_grid(GridMap(occ, 0.05, (-3.2, 1.7, yaw)), 0.1)


def _centres(domain: CoverageDomain, n: int, seed: int) -> np.ndarray:
    """``n`` robots on free cell centres: lines to other centres graze cell corners."""
    free = np.argwhere(domain.free)
    pick = free[np.random.default_rng(seed).choice(len(free), n, replace=False)]
    return domain.to_map(pick[:, ::-1] + 0.5)


def test_window_holds_the_free_space_and_a_ring_from_a_tile_corner():
    domain = _slam_like()
    window = free_window(domain)
    assert window is not None
    rows, cols = window
    assert rows.start % SIGHT_TILE == 0 and cols.start % SIGHT_TILE == 0
    inside = np.zeros(domain.shape, dtype=bool)
    inside[window] = True
    assert domain.free[~inside].sum() == 0
    r, c = np.nonzero(domain.free)
    ring = 1 + int(np.ceil(domain.robot_radius / domain.resolution))
    assert r.min() - rows.start >= ring and rows.stop - 1 - r.max() >= ring
    assert c.min() - cols.start >= ring and cols.stop - 1 - c.max() >= ring
    assert (rows.stop - rows.start) * (cols.stop - cols.start) < 0.5 * domain.free.size


def test_nothing_is_cut_where_the_free_space_fills_the_grid_or_on_a_chart():
    assert free_window(world_domain(load_world(shared_map("depot")), 0.105)) is None
    assert free_window(sphere_domain(48)) is None
    assert free_window(torus_domain(48, obstacles=((2.0, 2.0, 2.6, 3.2),))) is None


@pytest.mark.parametrize("yaw", [0.0, 0.7])
def test_cut_domain_tessellates_as_the_whole_one(yaw):
    domain = _slam_like(yaw)
    window = free_window(domain)
    cut = cropped(domain, window)
    for seed, on_centres in ((1, True), (2, False)):
        P = _centres(domain, 6, seed) if on_centres else random_points(domain, 6, 0, seed)
        gens = [Generator(p) for p in P]
        whole, part = tessellate(domain, gens), tessellate(cut, gens)
        assert np.array_equal(part.labels, whole.labels[window])
        assert np.array_equal(part.distances, whole.distances[window])
        assert np.array_equal(part.masses, whole.masses)
        assert np.allclose(cut.to_map(cut.to_grid(P)), P, rtol=0.0, atol=1e-12)


@pytest.mark.parametrize("source, power", [("slam", False), ("slam", True),
                                           ("tb3_sandbox", False), ("tb3_sandbox", True)])
def test_team_step_on_the_window_is_the_whole_domains(source, power):
    domain = _slam_like(0.3) if source == "slam" else world_domain(
        load_world(shared_map(source)), 0.105)
    team = GeodesicTeam(domain)
    for seed in range(4):
        P = _centres(domain, 8, seed) if seed % 2 else random_points(domain, 8, 0, seed)
        assert window_of(domain, P) is not None  # (the step below runs on the window)
        R = np.random.default_rng(seed).uniform(0.0, 1.0, 8) if power else np.zeros(8)
        fast, whole = team.step(P, R), team_cells(domain, P, R)
        assert np.array_equal(fast.labels, whole.cells())
        assert np.array_equal(fast.masses, whole.masses)
        assert np.array_equal(fast.costs, whole.costs)
        assert np.allclose(fast.centroids, P + whole.controls, rtol=0.0, atol=1e-12)
        assert np.allclose(fast.goals, whole.goals, rtol=0.0, atol=1e-12)


@pytest.mark.parametrize("power", [False, True])
def test_fast_tessellation_on_the_window_is_the_whole_domains(power):
    domain = world_domain(load_world(shared_map("tb3_sandbox")), 0.105)
    uncut = world_domain(load_world(shared_map("tb3_sandbox")), 0.105)
    uncut._cache["free_window"] = None  # (as a domain without a window: the whole grid)
    for seed in range(3):
        P = _centres(domain, 8, seed) if seed % 2 else random_points(domain, 8, 0, seed)
        gens = [Generator(p, 0.4 * (k % 3) if power else 0.0) for k, p in enumerate(P)]
        assert window_of(domain, P) is not None and window_of(uncut, P) is None
        fast, whole = fast_tessellate(domain, gens), fast_tessellate(uncut, gens)
        assert np.array_equal(fast.labels, whole.labels)
        assert np.array_equal(fast.distances, whole.distances)
        assert np.array_equal(fast.masses, whole.masses)
        assert np.array_equal(fast.costs, whole.costs)
        assert fast.unassigned == whole.unassigned


def test_a_robot_off_the_free_space_steps_on_the_whole_domain():
    """A robot on a blocked cell snaps to its nearest free cell over the whole grid."""
    domain = _slam_like()
    team = GeodesicTeam(domain)
    P = np.vstack([random_points(domain, 4, 0, 5), domain.to_map(np.array([[20.5, 30.5]]))])
    assert window_of(domain, P) is None and window_of(domain, P[:4]) is not None
    fast, ref = team.step(P), team.reference_step(P)
    assert np.array_equal(fast.labels, ref.labels)
    assert np.allclose(fast.masses, ref.masses, rtol=1e-12, atol=0.0)
    assert np.allclose(fast.goals, ref.goals, rtol=0.0, atol=1e-9)
