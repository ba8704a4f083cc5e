"""RViz markers: cell outlines (against a slow edge count), the marker messages, and the live
marker node of a team (one outline per robot, stable ids, deleted when a robot leaves)."""

from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pytest
from conftest import REPO
from hypothesis import given, settings
from hypothesis import strategies as st
from rosutil import RosClient, domain_id, spin_until_exit

from coverage_ros.core.strategies.base import MODES, mode_code, mode_name
from coverage_ros.core.strategies.tangentbug.bug import BugMode
from coverage_ros.core.world.grid import GridMap
from coverage_ros.nodes import conversions as conv
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


def test_every_strategy_mode_has_a_code():
    assert all(m.value in MODES for m in BugMode)
    assert mode_name(mode_code("greedy")) == "greedy" and mode_code("nonsense") == -1
    assert mode_name(-1.0) == "" and mode_name(float("nan")) == "" and mode_name(99.0) == ""


def test_team_markers_replace_by_namespace_and_id_and_delete_who_left():
    from visualization_msgs.msg import Marker

    stamp = conv.to_time_msg(3.0)
    a = conv.RobotMarkers(0, (1.0, 0.0, 0.0), position=(1.0, 2.0), radius=0.1,
                          outline=np.array([[[0, 0], [1, 0]], [[1, 0], [1, 1]]], float),
                          goal=(2.0, 2.0), plan=np.array([[1.0, 2.0], [2.0, 2.0]]),
                          mode="lloyd")
    b = conv.RobotMarkers(4, (0.0, 0.0, 1.0))  # nothing known yet: all deleted
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    msg = conv.team_markers([a, b], [7], stamp, lifetime=5.0, region=(square,),
                            region_before=3)
    by = {(m.ns, m.id): m for m in msg.markers}
    assert len(by) == len(msg.markers) == 3 * len(conv.MARKER_KINDS) + 3
    outline = by[("region", 0)]
    assert outline.type == Marker.LINE_STRIP and len(outline.points) == 5  # closed
    assert by[("region", 1)].action == by[("region", 2)].action == Marker.DELETE
    cell = by[("cell", 0)]
    assert cell.type == Marker.LINE_LIST and cell.action == Marker.ADD and len(cell.points) == 4
    assert (cell.color.r, cell.color.b) == (1.0, 0.0) and cell.header.frame_id == "map"
    assert cell.lifetime.sec == 5
    assert by[("generator", 0)].scale.x == pytest.approx(0.2)
    assert by[("mode", 0)].text == "robot_0: lloyd"
    assert by[("goal", 0)].pose.position.x == 2.0 and len(by[("plan", 0)].points) == 2
    assert all(by[(k, 4)].action == Marker.DELETE for k in conv.MARKER_KINDS)
    assert all(by[(k, 7)].action == Marker.DELETE for k in conv.MARKER_KINDS)


def test_a_robots_line_markers_are_built_again_only_for_a_new_outline_or_plan():
    """The outline and plan markers (thousands of points for a large cell) are reused while
    the robot's outline and plan arrays are the same ones, with the new stamp; a new array
    gives new points."""
    from visualization_msgs.msg import Marker

    first, later = conv.to_time_msg(3.0), conv.to_time_msg(3.5)
    square = np.array([[[0, 0], [1, 0]], [[1, 0], [1, 1]], [[1, 1], [0, 1]], [[0, 1], [0, 0]]],
                      float)
    r = conv.RobotMarkers(2, (0.0, 1.0, 0.0), position=(0.5, 0.5), outline=square,
                          plan=np.array([[0.5, 0.5], [0.9, 0.9]]))

    def kinds(stamp):
        return {m.ns: m for m in conv.robot_markers(r, stamp, lifetime=5.0)}

    a = kinds(first)
    b = kinds(later)
    assert b["cell"] is a["cell"] and b["plan"] is a["plan"]
    assert b["cell"].header.stamp.nanosec == later.nanosec and len(b["cell"].points) == 8
    r.outline = square[:2] * 2.0  # a new cell
    c = kinds(later)
    assert c["cell"] is not a["cell"] and len(c["cell"].points) == 4
    assert c["cell"].points[1].x == 2.0 and c["plan"] is a["plan"]
    assert kinds(later)["cell"] is c["cell"]
    r.plan = None  # the plan went away: deleted, not the old one shown
    assert kinds(later)["plan"].action == Marker.DELETE
    # another lifetime (or frame) builds anew: a reused marker never carries stale settings
    assert conv.robot_markers(r, later, lifetime=2.0)[0].lifetime.sec == 2


@pytest.mark.integration
@pytest.mark.slow
@pytest.mark.lockstep
def test_a_team_shows_in_rviz_markers_and_a_robot_that_leaves_is_cleared(tmp_path):
    from visualization_msgs.msg import Marker, MarkerArray

    domain = domain_id(4)
    out = tmp_path / "team"
    client = RosClient(domain, "marker_watch")
    arrays = client.subscribe("/coverage/markers", MarkerArray)
    # Lock-step at most twice real time: a silent robot's markers go after 3 s of wall time.
    proc = subprocess.Popen(
        [str(REPO / ".venv" / "bin" / "coverage-team"), "--quiet", "--world", "empty",
         "--robots", "3", "--duration", "30", "--seed", "1", "--kill", "2@12", "--lockstep",
         "--rtf", "2",
         "--out", str(out), "--domain-id", str(domain)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        err = spin_until_exit(client, proc, 240)
    finally:
        client.close()
    assert proc.returncode == 0, err[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["metrics"]["H"] < summary["metrics"]["H_start"]
    assert len(arrays) >= 10
    outlines: dict[int, int] = {}
    deleted_at = None
    for k, arr in enumerate(arrays):
        keys = [(m.ns, m.id) for m in arr.markers]
        assert len(keys) == len(set(keys)) <= 3 * len(conv.MARKER_KINDS)  # replaced, not added
        assert {m.ns for m in arr.markers} <= set(conv.MARKER_KINDS)
        for m in arr.markers:
            assert m.id in (0, 1, 2) and m.header.frame_id == "map"
            if m.ns == "cell" and m.action == Marker.ADD:
                assert m.type == Marker.LINE_LIST and len(m.points) >= 8
                outlines[m.id] = outlines.get(m.id, 0) + 1
            if (m.ns, m.id, m.action) == ("cell", 2, Marker.DELETE) and deleted_at is None \
                    and outlines.get(2):
                deleted_at = k
    assert all(outlines.get(i, 0) >= 3 for i in (0, 1, 2)), outlines
    assert deleted_at is not None, "robot 2's markers were never deleted"
    later = [m for arr in arrays[deleted_at + 1:] for m in arr.markers if m.id == 2]
    assert all(m.action == Marker.DELETE for m in later)
    modes = {m.text for arr in arrays for m in arr.markers if m.ns == "mode"}
    assert any(t.startswith("robot_0: ") and t != "robot_0: " for t in modes), modes


def test_the_shipped_rviz_config_shows_the_map_the_markers_and_the_scans():
    import yaml

    config = yaml.safe_load((REPO / "config" / "coverage.rviz").read_text())
    manager = config["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "map"
    displays = {d["Class"].split("/")[-1]: d for d in manager["Displays"]}
    topics = {d["Topic"]["Value"] for d in manager["Displays"] if "Topic" in d}
    assert {"/map", "/coverage/markers", "/robot_0/scan"} <= topics
    assert displays["Map"]["Topic"]["Durability Policy"] == "Transient Local"  # as world_node
    assert set(displays["MarkerArray"]["Namespaces"]) == {*conv.MARKER_KINDS, "region"}
