"""Malformed messages for every topic the team's nodes subscribe to (hypothesis strategies),
and which node listens where (:data:`TOPICS`); ``bench/fuzz.py`` sends them to a live team.

Every node of the live team gets NaN and infinities, empty and huge arrays, grids whose size
does not match their data, wrong frames, unknown robot ids and out-of-order or impossible stamps
on each topic it subscribes.

Messages that could be well-formed requests are never sent on topics where they would change the
team on purpose (a valid polygon on ``/coverage/region``, a valid spawn request, a plausible
newer pose): those are inputs, not faults. ``/clock`` is left out on purpose: a second clock is
a second simulation, which the launcher and the robots stop for (``ClockGuard``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from hypothesis import strategies as st

NAN, INF = math.nan, math.inf
UNKNOWN_ID = 77  # a robot id nobody runs
F64_BAD = st.sampled_from([NAN, INF, -INF])
F64 = st.one_of(F64_BAD, st.floats(allow_nan=True, allow_infinity=True))
F32 = st.one_of(F64_BAD, st.floats(allow_nan=True, allow_infinity=True, width=32))
FRAMES = st.sampled_from(["", "map", "odom", "robot_0/odom", "robot_0/base_link", "nowhere",
                          "map" * 300])
# Not "": several inputs read an empty frame_id as the map frame, as RViz tools send it.
BAD_FRAMES = st.sampled_from(["odom", "robot_0/odom", "nowhere", "map " * 300, "/map/"])
UINT32 = st.integers(0, 2**32 - 1)


@st.composite
def stamps(draw, bad: bool = False):
    """A builtin_interfaces/Time: any (``bad``: before the run started or with nanosec >= 1e9,
    i.e. out of order or impossible)."""
    from builtin_interfaces.msg import Time

    if bad:
        return draw(st.one_of(
            st.builds(Time, sec=st.integers(-2**31, 0), nanosec=st.integers(0, 999_999_999)),
            st.builds(Time, sec=st.integers(0, 2**31 - 1),
                      nanosec=st.integers(1_000_000_000, 2**32 - 1))))
    return Time(sec=draw(st.integers(-2**31, 2**31 - 1)), nanosec=draw(UINT32))


def _header(draw, frame=FRAMES, bad_stamp: bool = False):
    from std_msgs.msg import Header

    return Header(stamp=draw(stamps(bad_stamp)), frame_id=draw(frame))


def _pose(draw, number=F64):
    from geometry_msgs.msg import Point, Pose, Quaternion

    return Pose(position=Point(x=draw(number), y=draw(number), z=draw(number)),
                orientation=Quaternion(x=draw(number), y=draw(number), z=draw(number),
                                       w=draw(number)))


@st.composite
def odometry(draw):
    """Always malformed: a non-finite pose, a frame other than map, or an old stamp."""
    from nav_msgs.msg import Odometry

    kind = draw(st.sampled_from(["nan", "frame", "stamp"]))
    msg = Odometry()
    msg.header = _header(draw, BAD_FRAMES if kind == "frame" else st.just("map"),
                         bad_stamp=kind == "stamp")
    msg.child_frame_id = draw(FRAMES)
    msg.pose.pose = _pose(draw, F64_BAD if kind == "nan" else st.floats(-1e3, 1e3))
    return msg


@st.composite
def laser_scans(draw):
    from sensor_msgs.msg import LaserScan

    n = draw(st.sampled_from([0, 1, 7, 360, 20_000]))
    return LaserScan(header=_header(draw), angle_min=draw(F32), angle_max=draw(F32),
                     angle_increment=draw(st.one_of(st.just(0.0), F32)),
                     range_min=draw(F32), range_max=draw(F32),
                     ranges=[draw(F32)] * n,
                     intensities=[draw(F32)] * draw(st.sampled_from([0, 3, n])))


@st.composite
def twists(draw):
    from geometry_msgs.msg import Twist, Vector3

    return Twist(linear=Vector3(x=draw(F64), y=draw(F64), z=draw(F64)),
                 angular=Vector3(x=draw(F64), y=draw(F64), z=draw(F64)))


@st.composite
def occupancy_grids(draw):
    """Always malformed: data whose length is not width x height, a resolution that is not a
    positive number, a non-finite origin or a frame other than map."""
    from nav_msgs.msg import OccupancyGrid

    msg = OccupancyGrid()
    kind = draw(st.sampled_from(["size", "resolution", "origin", "frame"]))
    msg.header = _header(draw, BAD_FRAMES if kind == "frame" else st.just("map"))
    w, h = draw(st.sampled_from([(0, 0), (1, 1), (3, 2), (40, 30), (4000, 4000)]))
    msg.info.width, msg.info.height = w, h
    msg.info.resolution = (draw(st.one_of(F64_BAD, st.floats(max_value=0.0, width=32)))
                           if kind == "resolution" else 0.05)
    msg.info.origin = _pose(draw, F64_BAD if kind == "origin" else st.just(0.0))
    n = w * h
    if kind == "size":
        n = draw(st.sampled_from([0, 1, 7, n + 1, max(n - 1, 0)]))
        n = n + 1 if n == w * h else n
    msg.data = [draw(st.integers(-128, 127))] * min(n, 200_000)  # 4000 x 4000: torn anyway
    return msg


@st.composite
def coverage_states(draw):
    """Always malformed: wrong frame, a non-finite position, extra names and values of
    different lengths, an acvt plan with too few points, or a huge extra table."""
    from coverage_msgs.msg import AcvtState, RobotState

    kind = draw(st.sampled_from(["frame", "nan", "lengths", "plan", "huge"]))
    msg = RobotState(header=_header(draw, BAD_FRAMES if kind == "frame" else st.just("map")),
                     robot_id=draw(st.integers(-5, 500)), x=draw(F64), y=draw(F64),
                     weight=draw(F64), radius=draw(F64), v_max=draw(F64), vx=draw(F64),
                     vy=draw(F64), mass=draw(F64), cost=draw(F64),
                     mode=draw(st.integers(0, 255)))
    if kind == "nan":
        setattr(msg, draw(st.sampled_from(["x", "y"])), draw(F64_BAD))
    elif kind == "lengths":
        msg.extra_names = ["a", "b", "c"]
        msg.extra_values = [draw(F64)] * draw(st.integers(0, 2))
    elif kind == "plan":
        msg.acvt = [AcvtState(plan_from=0, plan_ids=[1, 2, 3], plan_x=[draw(F64)],
                              plan_y=[draw(F64)] * 3)]
    elif kind == "huge":
        msg.extra_names = [f"k{i}" for i in range(20_000)]
        msg.extra_values = [draw(F64)] * 19_999
    return msg


@st.composite
def pose_stampeds(draw):
    from geometry_msgs.msg import PoseStamped

    return PoseStamped(header=_header(draw), pose=_pose(draw))


@st.composite
def paths(draw):
    from nav_msgs.msg import Path as PathMsg

    n = draw(st.sampled_from([0, 1, 2, 50, 20_000]))
    return PathMsg(header=_header(draw), poses=[draw(pose_stampeds())] * n)


@st.composite
def polygons(draw, always_bad: bool = True):
    """Polygons with a non-finite point, fewer than three points or a frame other than map."""
    from geometry_msgs.msg import Point32, PolygonStamped

    kind = draw(st.sampled_from(["nan", "few", "frame", "huge"]))
    n = {"few": draw(st.integers(0, 2)), "huge": 20_000}.get(kind, draw(st.integers(3, 12)))
    pts = [Point32(x=draw(st.floats(0, 8, width=32)), y=draw(st.floats(0, 8, width=32)))
           for _ in range(min(n, 12))]
    pts = (pts * (n // max(len(pts), 1) + 1))[:n] if pts else []
    if kind in ("nan", "huge") and pts:
        pts[draw(st.integers(0, len(pts) - 1))] = Point32(x=draw(F64_BAD), y=0.0)
    msg = PolygonStamped(header=_header(draw, BAD_FRAMES if kind == "frame"
                                        else st.just("map")))
    msg.polygon.points = pts
    return msg


@st.composite
def point_clouds(draw):
    from sensor_msgs.msg import PointCloud2, PointField

    fields = [PointField(name=draw(st.sampled_from(["x", "y", "hits", "cell", "?"])),
                         offset=draw(st.integers(0, 64)), datatype=draw(st.integers(0, 255)),
                         count=draw(st.integers(0, 4)))
              for _ in range(draw(st.integers(0, 4)))]
    n = draw(st.sampled_from([0, 3, 16, 100_000]))
    return PointCloud2(header=_header(draw), height=draw(st.integers(0, 3)),
                       width=draw(st.integers(0, 5000)), fields=fields,
                       is_bigendian=draw(st.booleans()), point_step=draw(st.integers(0, 64)),
                       row_step=draw(st.integers(0, 10**6)), data=bytes(n),
                       is_dense=draw(st.booleans()))


def _not_a_spawn_request(text: str) -> bool:
    import yaml

    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError:
        return True
    return data is not None and not isinstance(data, dict)


BAD_SPAWNS = ["{id: 0}", "{id: -3}", "{id: 1.5}", "{id: 9, pose: [nan, 1]}",
              "{id: 9, pose: [1, 2, 3, 4]}", "{id: 9, radius: -1}", "{id: 9, v_max: .inf}",
              "{id: 9, wheels: 3}", "{pose: 'here'}", "[1, 2, 3]", "{{{", "id: [",
              "{id: 9, pose: [100, 100]}", "{id: 9, radius: 50}"]


@st.composite
def spawn_requests(draw):
    from std_msgs.msg import String

    text = draw(st.one_of(st.sampled_from(BAD_SPAWNS),
                          st.text(min_size=1, max_size=200).filter(_not_a_spawn_request),
                          st.just("x" * 100_000)))
    return String(data=text)


@st.composite
def remove_requests(draw):
    from std_msgs.msg import Int32

    return Int32(data=draw(st.one_of(st.integers(-2**31, -1), st.integers(50, 2**31 - 1))))


@st.composite
def tf_messages(draw):
    """Transforms of robot 1's chain that are non-finite, non-normalisable or old; and any
    transform between frames nobody uses."""
    from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3
    from tf2_msgs.msg import TFMessage

    def one() -> TransformStamped:
        ours = draw(st.booleans())
        parent, child = (draw(st.sampled_from([("map", "robot_1/odom"),
                                               ("robot_1/odom", "robot_1/base_link")]))
                         if ours else (draw(FRAMES), draw(FRAMES)))
        kind = draw(st.sampled_from(["nan", "zero", "stamp"]))
        t = TransformStamped(header=_header(draw, st.just(parent), bad_stamp=kind == "stamp"),
                             child_frame_id=child)
        num = F64_BAD if kind == "nan" else st.floats(-10, 10)
        q = Quaternion(x=0.0, y=0.0, z=0.0, w=0.0) if kind == "zero" else \
            Quaternion(x=draw(num), y=draw(num), z=draw(num), w=draw(num))
        t.transform = Transform(translation=Vector3(x=draw(num), y=draw(num), z=draw(num)),
                                rotation=q)
        return t

    n = draw(st.sampled_from([0, 1, 3, 500]))
    return TFMessage(transforms=[one() for _ in range(min(n, 5))] * max(1, n // 5) if n else [])


@st.composite
def world_statuses(draw):
    from coverage_msgs.msg import SimulatedRobot, WorldStatus

    robots = [SimulatedRobot(id=draw(st.sampled_from([0, 77, -1, 2**31 - 1])), x=draw(F64),
                             y=draw(F64), yaw=draw(F64), path_length=draw(F64),
                             min_separation=draw(F64), radius=draw(F64),
                             collisions=draw(st.integers(0, 2**32 - 1)))
              for _ in range(draw(st.integers(0, 4)))]
    return WorldStatus(header=_header(draw), world=draw(st.text(max_size=30)),
                       real_time_factor=draw(F64), robots=robots)


def empties():
    """Nothing to get wrong in an Empty: many of them (a flood)."""
    from std_msgs.msg import Empty

    return st.integers(0, 10**9).map(lambda _: Empty())


@dataclass(frozen=True)
class Target:
    topic: str
    type_name: str  # "package/msg/Type"
    strategy: Callable[[], Any]
    nodes: tuple[str, ...]  # which of the team's nodes subscribe to it
    qos: str = "team"  # "team" (reliable), "latched" (transient local), "best_effort"


U = f"/robot_{UNKNOWN_ID}"
TOPICS: tuple[Target, ...] = (
    Target("/robot_0/ground_truth", "nav_msgs/msg/Odometry", odometry, ("robot_0", "bridge")),
    Target("/robot_0/scan", "sensor_msgs/msg/LaserScan", laser_scans, ("robot_0", "bridge"),
           "best_effort"),
    Target("/robot_2/scan", "sensor_msgs/msg/LaserScan", laser_scans, ("robot_2", "bridge"),
           "best_effort"),
    Target("/robot_0/cmd_vel", "geometry_msgs/msg/Twist", twists, ("world",)),
    Target("/robot_0/teleop/cmd_vel", "geometry_msgs/msg/Twist", twists, ("robot_0",)),
    Target("/map", "nav_msgs/msg/OccupancyGrid", occupancy_grids,
           ("robot_0", "robot_1", "bridge"), "latched"),
    Target("/robot_1/coverage_state", "coverage_msgs/msg/RobotState", coverage_states,
           ("robot_0", "robot_2", "bridge", "markers")),
    Target(f"{U}/coverage_state", "coverage_msgs/msg/RobotState", coverage_states,
           ("robot_0", "robot_1", "robot_2", "bridge", "markers")),
    Target(f"{U}/goal_pose", "geometry_msgs/msg/PoseStamped", pose_stampeds,
           ("bridge", "markers")),
    Target(f"{U}/plan", "nav_msgs/msg/Path", paths, ("bridge", "markers")),
    Target(f"{U}/cell", "nav_msgs/msg/OccupancyGrid", occupancy_grids, ("bridge", "markers")),
    Target(f"{U}/cell_polygon", "geometry_msgs/msg/PolygonStamped", polygons, ("bridge",)),
    Target(f"{U}/observations", "sensor_msgs/msg/PointCloud2", point_clouds,
           ("robot_2", "bridge")),
    Target("/coverage/region", "geometry_msgs/msg/PolygonStamped", polygons,
           ("robot_0", "robot_1", "robot_2", "bridge", "markers"), "latched"),
    Target("/coverage/region/clear", "std_msgs/msg/Empty", empties,
           ("robot_0", "robot_1", "robot_2", "bridge", "markers")),
    Target("/world/spawn", "std_msgs/msg/String", spawn_requests, ("world",)),
    Target("/world/remove", "std_msgs/msg/Int32", remove_requests, ("world",)),
    Target("/tf", "tf2_msgs/msg/TFMessage", tf_messages, ("robot_1",)),
    Target("/tf_static", "tf2_msgs/msg/TFMessage", tf_messages, ("robot_1",), "latched"),
    Target("/world/robots", "coverage_msgs/msg/WorldStatus", world_statuses,
           ("bridge",)),
)


def message_type(type_name: str):
    """The message class of ``package/msg/Type``."""
    import importlib

    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)
