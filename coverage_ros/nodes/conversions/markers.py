"""RViz markers of a coverage team (``visualization_msgs/MarkerArray`` on ``/coverage/markers``).

Each robot ``k`` owns one marker per kind, always with id ``k`` in the kind's namespace, so a new
array replaces the previous markers instead of adding to them:

* ``cell`` - LINE_LIST, the outline of the robot's cell, in the robot's colour;
* ``generator`` - CYLINDER at the generator, the robot's diameter;
* ``goal`` - SPHERE at the goal;
* ``plan`` - LINE_STRIP along the planned path;
* ``mode`` - TEXT_VIEW_FACING above the robot: ``robot_<k>: <mode>``.

A robot that left gets a DELETE of each of its markers (same namespaces and ids). The region of
interest is namespace ``region``: a closed white LINE_STRIP per polygon, ids 0, 1, ...
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from coverage_ros.core.world.robot import TB3_RADIUS
from coverage_ros.nodes.conversions.basics import MAP_FRAME

#: The namespaces of a robot's markers (README "RViz").
MARKER_KINDS = ("cell", "generator", "goal", "plan", "mode")


@dataclass
class RobotMarkers:
    """What is drawn of one robot (map frame, metres); None / empty: not drawn."""

    robot_id: int
    color: tuple[float, float, float]  # RGB in [0, 1]
    position: tuple[float, float] | None = None
    radius: float = TB3_RADIUS
    outline: np.ndarray | None = None  # (K, 2, 2) segments
    goal: tuple[float, float] | None = None
    plan: np.ndarray | None = None  # (M, 2)
    mode: str = ""
    # kind -> (the outline or plan array it was built from, its marker): a line marker of
    # thousands of points is rebuilt only when a new array came (building 64 robots' outlines
    # at 2 Hz took two fifths of the marker node's CPU); its stamp is set anew on every use
    built: dict = field(default_factory=dict, repr=False, compare=False)


def _marker(kind: str, rid: int, mtype: int, stamp: Time, frame: str,
            lifetime: float) -> Marker:
    m = Marker()
    m.header.stamp = stamp
    m.header.frame_id = frame
    m.ns = kind
    m.id = int(rid)
    m.type = mtype
    m.action = Marker.ADD
    m.pose.orientation.w = 1.0
    m.lifetime = _duration(lifetime)
    return m


def _duration(seconds: float) -> Duration:
    return Duration(sec=int(seconds), nanosec=int((seconds % 1.0) * 1e9))


def _points(xy: np.ndarray, z: float = 0.0) -> list[Point]:
    return [Point(x=float(x), y=float(y), z=z) for x, y in np.asarray(xy).reshape(-1, 2)]


def _color(rgb, alpha: float = 1.0) -> ColorRGBA:
    return ColorRGBA(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=float(alpha))


def robot_markers(r: RobotMarkers, stamp: Time, frame: str = MAP_FRAME,
                  lifetime: float = 0.0) -> list[Marker]:
    """The markers of one robot (kinds it has nothing for are deleted, so a goal that went
    away does not linger). ``lifetime`` 0: until replaced."""
    out = []
    rid = r.robot_id

    def add(kind: str, mtype: int) -> Marker:
        m = _marker(kind, rid, mtype, stamp, frame, lifetime)
        m.color = _color(r.color)
        out.append(m)
        return m

    def lines(kind: str, mtype: int, xy: np.ndarray, width: float, z: float) -> None:
        held = r.built.get(kind)
        if held is not None and held[0] is xy and held[1].lifetime == _duration(lifetime) \
                and held[1].header.frame_id == frame:
            held[1].header.stamp = stamp
            out.append(held[1])
            return
        m = add(kind, mtype)
        m.scale.x = width
        m.points = _points(xy, z)
        r.built[kind] = (xy, m)

    if r.outline is not None and len(r.outline):
        lines("cell", Marker.LINE_LIST, r.outline, 0.03, 0.01)
    else:
        out.append(delete_marker("cell", rid, stamp, frame))
    if r.position is not None:
        m = add("generator", Marker.CYLINDER)
        m.pose.position = Point(x=float(r.position[0]), y=float(r.position[1]), z=0.05)
        m.scale.x = m.scale.y = 2.0 * float(r.radius)
        m.scale.z = 0.1
        m = add("mode", Marker.TEXT_VIEW_FACING)
        m.pose.position = Point(x=float(r.position[0]), y=float(r.position[1]), z=0.4)
        m.scale.z = 0.18
        m.text = f"robot_{rid}: {r.mode}" if r.mode else f"robot_{rid}"
    else:
        out += [delete_marker(k, rid, stamp, frame) for k in ("generator", "mode")]
    if r.goal is not None:
        m = add("goal", Marker.SPHERE)
        m.pose.position = Point(x=float(r.goal[0]), y=float(r.goal[1]), z=0.05)
        m.scale.x = m.scale.y = m.scale.z = 0.12
    else:
        out.append(delete_marker("goal", rid, stamp, frame))
    if r.plan is not None and len(r.plan) >= 2:
        lines("plan", Marker.LINE_STRIP, r.plan, 0.02, 0.02)
    else:
        out.append(delete_marker("plan", rid, stamp, frame))
    return out


def delete_marker(kind: str, rid: int, stamp: Time, frame: str = MAP_FRAME) -> Marker:
    m = _marker(kind, rid, Marker.CYLINDER, stamp, frame, 0.0)
    m.action = Marker.DELETE
    return m


def region_markers(polygons, shown_before: int, stamp: Time, frame: str = MAP_FRAME,
                   lifetime: float = 0.0) -> list[Marker]:
    """The region's outlines (ids 0..n-1) and deletions of ids n..``shown_before`` - 1."""
    out = []
    for k, poly in enumerate(polygons):
        m = _marker("region", k, Marker.LINE_STRIP, stamp, frame, lifetime)
        m.color = _color((1.0, 1.0, 1.0))
        m.scale.x = 0.05
        P = np.asarray(poly, dtype=np.float64).reshape(-1, 2)
        m.points = _points(np.vstack([P, P[:1]]), 0.03)
        out.append(m)
    out += [delete_marker("region", k, stamp, frame) for k in range(len(polygons), shown_before)]
    return out


def team_markers(robots: list[RobotMarkers], left: list[int], stamp: Time,
                 frame: str = MAP_FRAME, lifetime: float = 0.0,
                 region: tuple = (), region_before: int = 0) -> MarkerArray:
    """One array: every robot's markers, deletions for the robots in ``left``, and the region
    of interest's polygons (``region_before``: how many the previous array had)."""
    msg = MarkerArray()
    msg.markers.extend(region_markers(region, region_before, stamp, frame, lifetime))
    for r in robots:
        msg.markers.extend(robot_markers(r, stamp, frame, lifetime))
    for rid in left:
        msg.markers.extend(delete_marker(k, rid, stamp, frame) for k in MARKER_KINDS)
    return msg
