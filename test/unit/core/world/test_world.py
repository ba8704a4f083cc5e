"""World YAML parsing, validation and rasterisation; start placement."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from conftest import WORLDS, shared_map

from coverage_ros.core.world import clearance, cluster_starts, load_world, parse_world
from coverage_ros.core.world.robot import TB3_RADIUS
from coverage_ros.errors import WorldError


@pytest.mark.parametrize("path", sorted(WORLDS.glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_worlds_load(path):
    world = load_world(path)
    grid = world.grid
    free = grid.free_mask()
    assert 0.5 < free.mean() < 1.0  # the open field (gaussians) is 99.0 % free
    # The arena is walled: the outer ring of cells is occupied.
    assert not free[0].any() and not free[-1].any()
    assert not free[:, 0].any() and not free[:, -1].any()


def test_raster_marks_obstacles_where_they_are():
    world = parse_world({"bounds": [0, 0, 4, 3], "resolution": 0.1, "obstacles": [
        {"type": "circle", "center": [1, 1], "radius": 0.5},
        {"type": "box", "center": [3, 2], "size": [0.6, 0.4]},
    ]})
    grid = world.grid
    occ = grid.occupied_mask()

    def at(x, y):
        r, c = grid.world_to_cell(np.array([x, y]))
        return bool(occ[r, c])

    assert at(1.0, 1.0) and at(1.4, 1.0) and not at(1.6, 1.0)
    assert at(3.0, 2.0) and at(3.25, 2.15) and not at(3.4, 2.0)
    assert not at(2.0, 1.5)
    # Area of the circle in cells is close to pi r^2 (rasterised with a half-cell margin).
    X, Y = grid.all_cell_centers()
    near_circle = (np.hypot(X - 1, Y - 1) < 0.9)
    circle_cells = (occ & near_circle).sum() * 0.01
    assert math.pi * 0.5 ** 2 < circle_cells < math.pi * 0.6 ** 2


def test_solid_cells_lie_wholly_in_obstacles_or_outside_the_arena():
    """A box whose faces run through rows of cell centres: the cells it covers half are
    occupied on the raster (a robot must not enter them) but not solid - a lidar beam grazing
    the face rightly sees their free half. Cells with every corner in an obstacle are."""
    world = parse_world({"bounds": [0, 0, 4, 3], "resolution": 0.1, "obstacles": [
        {"type": "box", "center": [2.0, 1.5], "size": [0.4, 0.3]},  # x 1.8-2.2, y 1.35-1.65
        {"type": "box", "center": [1.0, 1.0], "size": [0.3, 0.2]},  # two boxes sharing the
        {"type": "box", "center": [1.3, 1.0], "size": [0.3, 0.2]},  # cells of x 1.1-1.2
    ]})
    grid, solid = world.grid, world.solid

    def cell(x, y):
        r, c = grid.world_to_cell(np.array([x, y]))
        return int(r), int(c)

    occupied = grid.occupied_mask()
    box = [cell(x, y) for x in (1.85, 1.95, 2.05, 2.15) for y in (1.35, 1.45, 1.55, 1.65)]
    assert all(occupied[rc] for rc in box)
    assert {rc for rc in box if solid[rc]} == {cell(x, y) for x in (1.85, 1.95, 2.05, 2.15)
                                                for y in (1.45, 1.55)}
    assert solid[cell(1.15, 0.95)] and solid[cell(1.15, 1.05)]  # corners in one box or other
    assert solid[cell(0.95, 0.95)] and not solid[cell(0.85, 0.95)]  # x 0.8-0.9: half in
    assert not solid[cell(3.0, 2.5)]
    assert solid[0, :].all() and solid[:, -1].all()  # the ring outside the arena
    # Solid cells are a part of the occupied ones.
    assert not (solid & ~occupied).any()


def test_world_on_top_of_a_map_server_map():
    base = shared_map("depot")
    world = parse_world({"map": str(base), "obstacles": [
        {"type": "box", "center": [10, 7], "size": [1, 1]}]})
    assert world.grid.shape == world.base_map.shape
    r, c = world.grid.world_to_cell(np.array([10.0, 7.0]))
    assert world.grid.occupancy[r, c] == 100
    # Solid: the map's blocked cells, whatever an obstacle covers of them, and the box's cells.
    blocked = world.base_map.occupied_mask(unknown_is_occupied=False)
    assert world.solid[r, c] and not (blocked & ~world.solid).any()
    X, Y = world.grid.all_cell_centers()
    r0, c0 = np.argwhere(blocked)[len(np.argwhere(blocked)) // 2]  # a wall of the depot
    over = parse_world({"map": str(base), "obstacles": [
        {"type": "circle", "center": [float(X[r0, c0]), float(Y[r0, c0])], "radius": 0.3}]})
    assert not (blocked & ~over.solid).any()


@pytest.mark.parametrize("data, where", [
    ({"bounds": [0, 0, 5, 5], "colour": "red"}, "colour: unknown key"),
    ({"bounds": [0, 0, -5, 5]}, "bounds: need xmin < xmax"),
    ({}, "bounds: required when no 'map'"),
    ({"bounds": [0, 0, 5, 5], "obstacles": [{"type": "blob"}]}, r"obstacles\[0\].type: unknown"),
    ({"bounds": [0, 0, 5, 5], "obstacles": [
        {"type": "circle", "center": [1, 1], "radius": -1}]},
     r"obstacles\[0\].radius: must be > 0"),
    ({"bounds": [0, 0, 5, 5], "obstacles": [
        {"type": "box", "center": [1, 1], "size": [1, 1], "height": 2}]},
     r"obstacles\[0\].height: unknown key"),
    ({"bounds": [0, 0, 5, 5], "robots": [{"pose": [1, 1, 0], "radius": 0}]},
     r"robots\[0\].radius: must be > 0"),
    ({"bounds": [0, 0, 5, 5], "robots": [[9, 1, 0]]}, r"robots\[0\]: start is outside the map"),
    ({"bounds": [0, 0, 5, 5], "robots": [[1, 1, 0]],
      "obstacles": [{"type": "circle", "center": [1, 1], "radius": 0.3}]},
     r"robots\[0\]: start \(1, 1\) is inside an obstacle"),
    ({"bounds": [0, 0, 5, 5], "robots": [[1, 1, 0], [1.1, 1, 0]]}, r"robots\[1\]: .* overlaps"),
    ({"bounds": [0, 0, 5, 5], "robots": [[0.05, 1, 0]]},
     r"robots\[0\]: .*inside an obstacle or wall"),
    ({"bounds": [0, 0, 5, 5], "density": {"type": "gaussian_mixture", "components": [
        {"mean": [1, 1], "sigma": -2}]}}, r"density.components\[0\].sigma: must be a number > 0"),
    ({"bounds": [0, 0, 5, 5], "lidar": {"beams": 0}}, "lidar.beams: must be an integer >= 1"),
])
def test_bad_world_is_named(tmp_path, data, where):
    path = tmp_path / "w.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(WorldError, match=where) as info:
        load_world(path)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value)


def test_heterogeneous_robots_and_defaults():
    world = parse_world({"bounds": [0, 0, 5, 5], "robot": {"v_max": 0.3},
                         "robots": [[1, 1, 0], {"pose": [2, 2, 1.0], "radius": 0.2,
                                                "lidar": {"beams": 90}}]})
    assert world.robot_spec(0).radius == TB3_RADIUS and world.robot_spec(0).v_max == 0.3
    assert world.robot_spec(1).radius == 0.2 and world.robot_spec(1).lidar.beams == 90
    assert world.robot_spec(5).v_max == 0.3  # beyond the listed starts: world default


def test_cluster_is_compact_free_and_seeded():
    world = load_world(WORLDS / "office.yaml")
    grid = world.grid
    a = cluster_starts(grid, 6, TB3_RADIUS, np.random.default_rng(3))
    b = cluster_starts(grid, 6, TB3_RADIUS, np.random.default_rng(3))
    c = cluster_starts(grid, 6, TB3_RADIUS, np.random.default_rng(4))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    for x, y, _ in a:
        assert clearance(world, x, y) >= TB3_RADIUS
    d = np.hypot(*(a[:, None, :2] - a[None, :, :2]).transpose(2, 0, 1))
    assert d[np.triu_indices(6, 1)].min() >= 2 * TB3_RADIUS
    assert d.max() < 1.5  # compact: all within 1.5 m of each other


def test_cluster_on_real_map():
    world = load_world(shared_map("tb3_sandbox"))
    starts = cluster_starts(world.grid, 10, TB3_RADIUS, np.random.default_rng(0))
    for x, y, _ in starts:
        assert clearance(world, x, y) >= TB3_RADIUS
