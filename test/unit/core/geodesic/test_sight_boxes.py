"""Depth maps of the occluders in a box around the segments asked about (LineOfSight.
visible_each), and the tiles of a kept map grown from such boxes to the whole domain
(sight_tiles_whole), answer as the whole domain's map does."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.tangents import SIGHT_TILE
from coverage_ros.core.world.grid import OCCUPIED, GridMap


def _domain(rng: np.random.Generator, share: float) -> CoverageDomain:
    occ = np.where(rng.random((150, 210)) < share, OCCUPIED, 0).astype(np.int8)
    occ[60:64, 20:180] = OCCUPIED  # a long wall: far occluders in every bin along it
    return CoverageDomain.from_grid(GridMap(occ, 0.05, (0.0, 0.0, 0.0)), 0.0)


@pytest.mark.parametrize("share", [0.003, 0.02, 0.08])
def test_box_maps_answer_as_the_whole_domains_map(share):
    rng = np.random.default_rng(int(share * 1000))
    domain = _domain(rng, share)
    H, W = domain.shape
    whole = 2.0 * math.hypot(H, W)
    for _ in range(12):
        origin = rng.uniform([0.0, 0.0], [W, H])
        depths: dict = {}
        for _ in range(4):  # clusters near and far, the kept map growing between them
            centre = rng.uniform([0.0, 0.0], [W, H])
            spread = rng.uniform(1.0, 60.0)
            points = centre + rng.normal(0.0, spread, (300, 2))
            expected = domain.visible_mask(origin, points, whole)
            assert np.array_equal(domain.visible_each(origin, points, depths), expected)
        nx, ny = -(-W // SIGHT_TILE), -(-H // SIGHT_TILE)
        ids = rng.choice(nx * ny, 12, replace=False)
        states = domain.sight_tiles_whole(origin, depths)[ids]
        for tile, state in zip(ids, states, strict=True):
            x0, y0 = (tile % nx) * SIGHT_TILE, (tile // nx) * SIGHT_TILE
            yy, xx = np.mgrid[y0:y0 + SIGHT_TILE, x0:x0 + SIGHT_TILE]
            cells = np.stack([xx.ravel() + 0.5, yy.ravel() + 0.5], axis=-1)
            seen = domain.visible_mask(origin, cells, whole)
            if state == 1:
                assert seen.all()
            elif state == 0:
                assert not seen.any()


def test_box_maps_along_a_wall_answer_as_the_whole_domains_map():
    """Points in the row beside a wall, seen along it: the wall's occluders lie a cell off the
    segments, outside the points' own box, and still hide the far ones."""
    rng = np.random.default_rng(5)
    domain = _domain(rng, 0.0)
    H, W = domain.shape
    whole = 2.0 * math.hypot(H, W)
    answers = []
    for row in (58.5, 59.5, 64.5, 65.5):  # the rows either side of the wall (60..63)
        for x in (3.5, 15.5, 100.3):
            origin = np.array([x, row + rng.uniform(-0.4, 0.4)])
            points = np.stack([np.arange(W) + 0.5, np.full(W, row)], axis=-1)
            expected = domain.visible_mask(origin, points, whole)
            assert np.array_equal(domain.visible_each(origin, points, {}), expected)
            answers.append(expected)
    assert not np.concatenate(answers).all()  # the wall hides some of them


def _walled(inner_wall: bool) -> CoverageDomain:
    occ = np.zeros((60, 80), dtype=np.int8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = OCCUPIED
    if inner_wall:
        occ[10:50, 40:42] = OCCUPIED
    return CoverageDomain.from_grid(GridMap(occ, 0.1, (0.0, 0.0, 0.0)), 0.1)


def test_every_free_cell_is_seen_from_anywhere_in_an_open_field():
    """Free cells filling a rectangle: a segment between two of its points stays in it. The
    discs of the walls' cells, binned by angle, hid 36 free cells grazing the walls from the
    field's centre and 694 from a point beside a wall."""
    domain = _walled(False)
    rows, cols = np.nonzero(domain.free)
    assert domain.free_rectangle == (cols.min(), rows.min(), cols.max() + 1, rows.max() + 1)
    centers = np.stack([cols + 0.5, rows + 0.5], axis=1).astype(np.float64)
    for origin in ([40.0, 30.0], [2.6, 2.6], [2.1, 30.0], [40.0, 2.05]):
        depths: dict = {}
        assert domain.visible_mask(np.array(origin), centers, 200.0).all()
        assert domain.visible_each(np.array(origin), centers, depths).all()
        assert (domain.sight_tiles(np.array(origin), 200.0, depths) == 1).all()


def test_a_wall_inside_the_field_still_hides_the_cells_behind_it():
    domain = _walled(True)
    assert domain.free_rectangle is None
    behind = np.array([[60.5, 30.5], [70.5, 25.5]])
    assert not domain.visible_mask(np.array([20.0, 30.0]), behind, 200.0).any()
