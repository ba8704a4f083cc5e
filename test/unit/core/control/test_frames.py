"""The frame math of /tf like a real robot's (coverage_ros/core/control/frames.py): compose,
invert, and the tree walked from base_link up to map."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from coverage_ros.core.control.frames import FrameTree, compose, invert

poses = st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-math.pi, math.pi))


@given(poses, poses, poses)
def test_compose_is_associative_and_invert_undoes_it(a, b, c):
    left, right = compose(compose(a, b), c), compose(a, compose(b, c))
    assert left[:2] == pytest.approx(right[:2], abs=1e-9)
    assert math.cos(left[2] - right[2]) == pytest.approx(1.0)
    ident = compose(a, invert(a))
    assert ident[:2] == pytest.approx((0.0, 0.0), abs=1e-9) and math.sin(ident[2]) == \
        pytest.approx(0.0, abs=1e-12)


def test_the_tree_walks_from_base_link_up_to_map():
    tree = FrameTree()
    assert tree.lookup("map", "r/base_link") is None
    tree.set("map", "r/odom", (1.0, 0.0, math.pi / 2), 5.0)
    tree.set("r/odom", "r/base_footprint", (2.0, 0.0, 0.0), 6.0)
    tree.set("/r/base_footprint", "r/base_link", (0.0, 0.0, 0.0), -math.inf)  # static
    pose, stamp = tree.lookup("map", "r/base_link")
    assert pose == pytest.approx((1.0, 2.0, math.pi / 2)) and stamp == 5.0
    tree.set("map", "r/odom", (9.0, 9.0, 0.0), 4.0)  # older than the one kept: ignored
    assert tree.lookup("map", "r/base_link")[0] == pytest.approx((1.0, 2.0, math.pi / 2))
    tree.set("r/base_link", "map", (0.0, 0.0, 0.0), 7.0)  # someone publishes a loop
    assert tree.lookup("world", "r/base_link") is None  # bounded, not endless
    with pytest.raises(ValueError, match="not finite"):
        tree.set("map", "x", (math.nan, 0.0, 0.0), 1.0)
    with pytest.raises(ValueError, match="two different frames"):
        tree.set("a", "a", (0.0, 0.0, 0.0), 1.0)
