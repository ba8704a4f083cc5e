"""A region of interest at run time (coverage_ros/core/world/region.py): polygons checked as a
user types them and as they come through a message, the density kept inside, an impossible
region refused by the launcher (the live team: integration/test_team_region.py)."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from conftest import entry_point

from coverage_ros.core.world.grid import OCCUPIED, GridMap
from coverage_ros.core.world.region import Region, parse_region_text
from coverage_ros.errors import ConfigError


def team_cmd(*args: str) -> list[str]:
    """coverage-team with ``args``."""
    return [entry_point("coverage-team"), "--quiet", *args]


def test_region_text_and_polygons_are_checked():
    assert parse_region_text("0,0;1,0;1,1").shape == (3, 2)
    for bad, why in [("0,0;1,0", "at least 3"), ("0,0;1;1,1", "two numbers"),
                     ("a,b;1,0;1,1", "x,y;x,y"), ("0,0;1,1;2,2", "no area"),
                     ("0,0;nan,0;1,1", "finite")]:
        with pytest.raises(ConfigError, match=why) as err:
            parse_region_text(bad)
        assert str(err.value).startswith("--region")


def test_a_polygon_that_came_through_a_message_is_one_the_region_holds():
    """The launcher's start region reaches a robot as a parameter and again on the topic,
    with float32 points: the same polygon, which must not restart the robot's strategy."""
    from coverage_ros.nodes.region_input import SAME_POINT

    square = parse_region_text("-1.8,-1.8;1.0,-1.8;1.0,1.0;-1.8,1.0")
    echoed = square.astype(np.float32).astype(np.float64)  # geometry_msgs/Point32 on the wire
    assert not np.array_equal(echoed, square)
    region = Region((square,))
    assert region.holds(echoed, SAME_POINT) and not region.holds(echoed)
    assert not region.holds(echoed + 0.01, SAME_POINT) and not region.holds(echoed[:3])


def test_the_density_is_kept_inside_the_union_of_the_polygons():
    occ = np.zeros((40, 60), np.int8)
    occ[:, 30] = OCCUPIED  # a wall down the middle
    grid = GridMap(occ, 0.1)
    region = Region().with_polygon([[0, 0], [1, 0], [1, 1], [0, 1]]).with_polygon(
        [[4, 2.02], [5, 2.02], [5, 3.02]])  # no cell centre on an edge
    mask = region.mask(grid)
    X, Y = grid.all_cell_centers()
    square = (X < 1) & (Y < 1)
    triangle = (X > 4) & (X < 5) & (Y > 2.02) & (Y < X - 1.98)
    assert (mask == (square | triangle)).all()
    assert Region().mask(grid).all() and Region().everywhere
    w = region.restrict(np.ones(grid.shape), grid, grid.free_mask())
    assert w.sum() == pytest.approx((square | triangle).sum())
    with pytest.raises(ConfigError, match="no free space"):  # on the wall only
        Region().with_polygon([[2.98, 0], [3.08, 0], [3.08, 4], [2.98, 4]]).restrict(
            np.ones(grid.shape), grid, grid.free_mask())


def test_an_impossible_region_is_refused_before_anything_starts(tmp_path):
    proc = subprocess.run(team_cmd("--world", "empty", "--robots", "2", "--out",
                                   str(tmp_path / "t"), "--region", "20,20;21,20;21,21"),
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        line for line in proc.stderr.strip().splitlines() if "--region" in line]
    assert "holds no free space" in proc.stderr and not (tmp_path / "t").exists()


