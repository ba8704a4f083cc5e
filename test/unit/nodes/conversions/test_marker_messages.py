"""RViz marker messages of a team (coverage_ros/nodes/conversions/markers.py) and the shipped
RViz config that shows them."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REPO

from coverage_ros.nodes import conversions as conv


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
