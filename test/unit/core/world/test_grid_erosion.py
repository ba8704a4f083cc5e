"""The inflated free mask without the distance transform (grid.erode_by_disc) is the one the
distance transform gives (clearance > radius + res / 2), cell for cell."""

from __future__ import annotations

import numpy as np
import pytest

from coverage_ros.core.world.grid import OCCUPIED, UNKNOWN, GridMap


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("radius", [0.01, 0.025, 0.05, 0.105, 0.2, 0.5, 1.3])
def test_inflation_equals_the_distance_transforms(seed, radius):
    rng = np.random.default_rng(seed)
    occ = np.zeros((57, 83), dtype=np.int8)
    occ[rng.random(occ.shape) < 0.03] = OCCUPIED
    occ[rng.random(occ.shape) < 0.01] = UNKNOWN
    occ[20:30, 40:44] = OCCUPIED
    res = [0.05, 0.1, 0.03, 0.25][seed]
    grid = GridMap(occ, res, (1.0, -2.0, 0.3))
    for unknown_is_free in (False, True):
        ref = grid.clearance(unknown_is_free) > radius + 0.5 * res
        got = grid.inflated_free_mask(radius, unknown_is_free)
        assert np.array_equal(got, ref)


def test_inflation_at_exact_distances():
    """Resolution 1 m and radii that put blocked cells exactly at the reach."""
    occ = np.zeros((21, 21), dtype=np.int8)
    occ[10, 10] = OCCUPIED
    grid = GridMap(occ, 1.0, (0.0, 0.0, 0.0))
    for radius in (0.5, 1.5, 2.5, np.sqrt(2) - 0.5, np.sqrt(5) - 0.5, 4.5):
        ref = grid.clearance() > radius + 0.5
        assert np.array_equal(grid.inflated_free_mask(radius), ref), radius
