"""Cell outlines for RViz and rerun, against a slow edge count (coverage_ros/viz/outline.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coverage_ros.core.world.grid import GridMap
from coverage_ros.viz.outline import outline_segments


def test_outline_of_a_rectangle_is_its_four_sides():
    grid = GridMap(np.zeros((4, 5), np.int8), 0.5, (1.0, 2.0, 0.0))
    mask = np.zeros((4, 5), bool)
    mask[1:3, 1:4] = True
    segs = outline_segments(mask, grid)
    got = sorted(tuple(np.round(s.ravel(), 6)) for s in segs)
    assert got == sorted([(1.5, 2.5, 3.0, 2.5), (1.5, 3.5, 3.0, 3.5), (1.5, 2.5, 1.5, 3.5),
                          (3.0, 2.5, 3.0, 3.5)])
    assert outline_segments(np.zeros((4, 5), bool), grid).shape == (0, 2, 2)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2 ** 31 - 1), st.floats(-math.pi, math.pi))
def test_outline_length_equals_the_boundary_edges_counted_one_by_one(seed, yaw):
    """Parity with the obvious count: every unit edge between a cell in the mask and one
    outside it (or the border) is covered once by the merged segments, on a rotated grid."""
    rng = np.random.default_rng(seed)
    mask = rng.random((7, 9)) < 0.5
    grid = GridMap(np.zeros(mask.shape, np.int8), 0.1, (0.3, -0.2, yaw))
    edges = 0
    h, w = mask.shape
    for r in range(h):
        for c in range(w):
            if not mask[r, c]:
                continue
            for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                rr, cc = r + dr, c + dc
                edges += not (0 <= rr < h and 0 <= cc < w and mask[rr, cc])
    segs = outline_segments(mask, grid)
    length = np.hypot(*(segs[:, 1] - segs[:, 0]).T).sum()
    assert length == pytest.approx(edges * 0.1, abs=1e-9)
    # Every segment end lies on the lattice's corners (rotated with the grid).
    local = grid.world_to_grid(segs.reshape(-1, 2))
    np.testing.assert_allclose(local, np.round(local), atol=1e-6)
