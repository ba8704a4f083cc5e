"""marker_node: the team as RViz markers (``visualization_msgs/MarkerArray`` on
``/coverage/markers``).

It finds the robots itself from the ROS graph (every ``/<prefix><k>/coverage_state``), listens to
each robot's ``coverage_state``, ``cell``, ``goal_pose`` and ``plan``, and at ``rate`` publishes
one array with each robot's cell outline (in the robot's colour, the same as in rerun),
generator, goal, plan and mode, and the region of interest (``/coverage/region``)
(:mod:`coverage_ros.nodes.conversions.markers`). Markers keep
their namespace and id (= robot id), so each array replaces the previous one. A robot whose
``coverage_state`` has been silent for ``stale_after`` seconds (it publishes a few per second,
even paused) or whose topics are gone from the graph gets its markers deleted - a killed
process stays in the DDS graph until its lease runs out, tens of seconds later. In lock-step
(``/world/tick``) a robot the world still waits for is not silent: a team held at one tick while
one robot computes publishes no states, and a dead robot leaves the tick's members once the
world drops it (its ``lockstep_timeout``). A bad message is dropped with a throttled warning.

    ros2 run coverage_ros marker_node --ros-args -p use_sim_time:=true
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
from coverage_msgs.msg import LockstepTick, RobotState
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import OccupancyGrid, Path
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from visualization_msgs.msg import MarkerArray

from coverage_ros.core.strategies.base import mode_name
from coverage_ros.errors import ConfigError
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.parameters import declare_parameters
from coverage_ros.nodes.qos import TEAM_QOS, TICK_QOS, quiet_subscription
from coverage_ros.nodes.region_input import RegionInput
from coverage_ros.nodes.robot_graph import state_topics
from coverage_ros.nodes.runner import run_node
from coverage_ros.nodes.throttle import WarnThrottle
from coverage_ros.viz.colors import robot_color
from coverage_ros.viz.outline import outline_segments

DISCOVERY_PERIOD = 1.0  # [s] wall time between looks at the ROS graph
VANISH_CHECKS = 2  # graph looks without a coverage_state publisher before a robot is gone
TOPICS = {"coverage_state": RobotState, "cell": OccupancyGrid, "goal_pose": PoseStamped,
          "plan": Path}

PARAMETERS = {
    "robot_prefix": ("robot_", "namespace prefix of the team's robots"),
    "topic": ("/coverage/markers", "visualization_msgs/MarkerArray output topic"),
    "rate": (2.0, "[Hz] marker arrays per second of wall time (markers are replaced, never "
             "accumulated)"),
    "frame_id": ("map", "frame of the markers (the robots' map frame)"),
    "lifetime": (5.0, "[s] markers not refreshed this long vanish (e.g. this node stopped); "
                 "0: until replaced"),
    "stale_after": (3.0, "[s] wall time: a robot whose coverage_state is silent this long is "
                    "taken off (markers deleted) until it speaks again, unless a lock-step "
                    "world heard within this time still waits for it"),
}


class MarkerNode(Node):
    def __init__(self) -> None:
        super().__init__("coverage_markers")
        p = declare_parameters(self, PARAMETERS)
        if not (math.isfinite(p["rate"]) and p["rate"] > 0):
            raise ConfigError.at("rate", "must be a number > 0 [Hz]", p["rate"])
        if not (math.isfinite(p["lifetime"]) and p["lifetime"] >= 0):
            raise ConfigError.at("lifetime", "must be a number >= 0 [s]", p["lifetime"])
        if not (math.isfinite(p["stale_after"]) and p["stale_after"] > 0):
            raise ConfigError.at("stale_after", "must be a number > 0 [s]", p["stale_after"])
        self.stale_after = p["stale_after"]
        self.prefix, self.frame, self.lifetime = p["robot_prefix"], p["frame_id"], p["lifetime"]
        self.pub = self.create_publisher(MarkerArray, p["topic"], TEAM_QOS)
        self.robots: dict[int, conv.RobotMarkers] = {}
        self.subs: dict[int, list] = {}
        self._idle: dict[int, int] = {}
        self._heard: dict[int, float] = {}  # robot id -> time.monotonic() of its last state
        self._shown: set[int] = set()  # robots whose markers the last array added
        self._waited_for: frozenset[int] = frozenset()  # robot members of the last tick
        self._tick_heard = -math.inf  # time.monotonic() of the last /world/tick
        self._region_shown = 0  # polygons in the last array
        self._throttle = WarnThrottle(self.get_logger().warning)
        self.regions = RegionInput(self, lambda region: None, self._throttle.warn)
        self.create_subscription(LockstepTick, "/world/tick", self._on_tick, TICK_QOS,
                                 event_callbacks=quiet_subscription())
        # Both on the steady clock: a silent robot is judged in wall time, and markers stay
        # fresh while the simulation is paused or its /clock does not reach this node.
        wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(DISCOVERY_PERIOD, self._discover, clock=wall)
        self.create_timer(1.0 / p["rate"], self._publish, clock=wall)

    def _discover(self) -> None:
        found = {rid for rid, topic in state_topics(self.get_topic_names_and_types(),
                                                    self.prefix)
                 if self.count_publishers(topic) > 0}
        for rid in sorted(found - self.subs.keys()):
            self.robots[rid] = conv.RobotMarkers(rid, tuple(robot_color(rid) / 255.0))
            self.subs[rid] = [
                self.create_subscription(
                    msg_type, f"/{self.prefix}{rid}/{kind}",
                    self._guard(kind, rid), TEAM_QOS, event_callbacks=quiet_subscription())
                for kind, msg_type in TOPICS.items()]
            self.get_logger().info(f"robot {rid} joined")
        for rid in list(self.subs):
            self._idle[rid] = 0 if rid in found else self._idle.get(rid, 0) + 1
            if self._idle[rid] >= VANISH_CHECKS:
                for sub in self.subs.pop(rid):
                    self.destroy_subscription(sub)
                del self.robots[rid], self._idle[rid]
                self._heard.pop(rid, None)
                self.get_logger().info(f"robot {rid} left the graph")

    def _guard(self, kind: str, rid: int):
        handler = getattr(self, f"_on_{kind}")

        def run(msg) -> None:
            r = self.robots.get(rid)
            if r is None:
                return
            try:
                if msg.header.frame_id not in (self.frame, ""):
                    raise ValueError(f"frame_id {msg.header.frame_id!r}, expected {self.frame!r}")
                handler(r, msg)
                if kind == "coverage_state":
                    self._heard[rid] = time.monotonic()
            except Exception as exc:  # a bad message never takes the node down
                self._throttle.warn(f"{kind}{rid}", f"dropped a message on "
                                    f"/{self.prefix}{rid}/{kind}: {exc}")
        return run

    def _on_tick(self, msg: LockstepTick) -> None:
        # (the world re-publishes a tick it waits on every second of wall time)
        self._waited_for = frozenset(int(r) for r in msg.robots)
        self._tick_heard = time.monotonic()

    def _silent(self, rid: int, now: float) -> bool:
        """Whether robot ``rid`` has been silent for ``stale_after`` [s] of wall time and no
        lock-step world heard that long waits for it (module docstring)."""
        if now - self._heard.get(rid, -math.inf) <= self.stale_after:
            return False
        return not (rid in self._heard and rid in self._waited_for
                    and now - self._tick_heard <= self.stale_after)

    @staticmethod
    def _on_coverage_state(r: conv.RobotMarkers, msg: RobotState) -> None:
        v = conv.coverage_state_values(msg)
        x, y = v["x"], v["y"]
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"position ({x}, {y}) is not finite")
        r.position = (x, y)
        r.radius = v.get("radius", r.radius)
        r.mode = ("manual" if v.get("manual", 0.0) else "paused" if v.get("paused", 0.0)
                  else mode_name(v.get("mode", -1.0)))

    @staticmethod
    def _on_cell(r: conv.RobotMarkers, msg: OccupancyGrid) -> None:
        grid = conv.cell_grid_to_grid(msg)
        outline = None if grid is None else outline_segments(grid.occupancy == 100, grid)
        if not _same(outline, r.outline):  # (the same cell again keeps its built marker)
            r.outline = outline

    @staticmethod
    def _on_goal_pose(r: conv.RobotMarkers, msg: PoseStamped) -> None:
        x, y, _ = conv.pose_stamped_to_pose(msg)
        r.goal = (x, y) if math.isfinite(x) and math.isfinite(y) else None

    @staticmethod
    def _on_plan(r: conv.RobotMarkers, msg: Path) -> None:
        pts = conv.path_to_points(msg)
        plan = pts if len(pts) and np.isfinite(pts).all() else None
        if not _same(plan, r.plan):
            r.plan = plan

    def _publish(self) -> None:
        now = time.monotonic()
        active = [r for rid, r in sorted(self.robots.items()) if not self._silent(rid, now)]
        shown = {r.robot_id for r in active}
        gone = sorted(self._shown - shown)
        for rid in gone:
            self.get_logger().info(f"robot {rid} silent or gone: its markers are deleted")
        self._shown = shown
        region = self.regions.region.polygons
        if not active and not gone and not region and not self._region_shown:
            return
        stamp = self.get_clock().now().to_msg()
        self.pub.publish(conv.team_markers(active, gone, stamp, self.frame, self.lifetime,
                                           region, self._region_shown))
        self._region_shown = len(region)


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return a is b or (a is not None and b is not None and np.array_equal(a, b))


def main(args=None) -> int:
    return run_node("marker_node", MarkerNode, args, parameters=PARAMETERS)


if __name__ == "__main__":
    sys.exit(main())
