"""rerun_bridge: streams a running coverage team's ROS topics into one rerun recording.

It subscribes ``/clock``, ``/map`` and ``/world/robots`` and, for every robot it finds in the
ROS graph (namespaces ``/<robot_prefix><id>``, looked at every DISCOVERY_PERIOD; robots join and
vanish at any time), ``ground_truth``, ``scan``, ``goal_pose``, ``plan``, ``cell``,
``cell_polygon`` and ``coverage_state``. Everything is logged on the ``sim_time`` timeline at
the messages' stamps, in the entity layout of :mod:`coverage_ros.viz.recording`. Every
``metrics_period`` of sim time the coverage cost H and the cell masses of the robots' current
positions (power weights from their ``coverage_state``) are computed with the core, as
``coverage-plan`` does, on a worker thread so that messages keep flowing meanwhile.

Robot nodes need none of this: the bridge only listens, so real robots are viewed the same way.

    ros2 run coverage_ros rerun_bridge --ros-args -p record_path:=team.rrd -p world:=office
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path as FilePath

from coverage_msgs.msg import RobotState, WorldStatus
from geometry_msgs.msg import PolygonStamped, PoseStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from rclpy.clock import Clock as RclClock
from rclpy.clock import ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan, PointCloud2

from coverage_ros.core.world import load_world
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.bridge_config import PARAMETERS, BridgeConfig
from coverage_ros.nodes.parameters import declare_parameters
from coverage_ros.nodes.qos import (
    CLOCK_QOS,
    MAP_QOS,
    SCAN_QOS,
    STREAM_QOS,
    TEAM_QOS,
    quiet_subscription,
)
from coverage_ros.nodes.region_input import RegionInput
from coverage_ros.nodes.robot_graph import robot_topic_kinds
from coverage_ros.nodes.runner import run_node
from coverage_ros.nodes.throttle import WarnThrottle
from coverage_ros.worlds import resolve_world_path

DISCOVERY_PERIOD = 1.0  # [s] wall time between looks at the ROS graph for robots
VANISH_CHECKS = 2  # graph looks without any publisher before a robot counts as gone
# [s] wall time rerun collects rows into one chunk: every chunk costs ~1 KB of schema, so the
# default 0.2 s made most of a team's recording overhead; a viewer lags this much behind.
BATCH_PERIOD = 1.0
TOPICS = {  # per-robot topic: (message type, QoS)
    "ground_truth": (Odometry, STREAM_QOS),
    "scan": (LaserScan, SCAN_QOS),
    "goal_pose": (PoseStamped, TEAM_QOS),
    "plan": (Path, TEAM_QOS),
    "cell": (OccupancyGrid, TEAM_QOS),
    "cell_polygon": (PolygonStamped, TEAM_QOS),
    "observations": (PointCloud2, TEAM_QOS),
    "coverage_state": (RobotState, TEAM_QOS),
}
#: /world/robots values not plotted: the robot positions (shown as robots) and the fixed spec.
STATUS_SKIP = {"id", "x", "y", "yaw", "driving", "radius", "v_max", "w_max", "a_max", "alpha_max",
               "sensor_radius", "power_weight", "lidar_range_max"}


def type_name(msg_type: type) -> str:
    """``nav_msgs/msg/Odometry`` for the class ``Odometry`` (the ROS graph's spelling)."""
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


class RerunBridge(Node):
    """The rerun bridge node (see module docstring)."""

    def __init__(self) -> None:
        super().__init__("rerun_bridge")
        self.config = cfg = BridgeConfig(**declare_parameters(self, PARAMETERS))
        world = load_world(resolve_world_path(cfg.world)) if cfg.world else None
        from coverage_ros.viz.live_metrics import LiveMetrics
        from coverage_ros.viz.live_team import LiveTeam
        from coverage_ros.viz.recording import CoverageRecorder
        from coverage_ros.viz.web_viewer import WebViewerServer

        self.rec = CoverageRecorder(cfg.recording_id or None, batch_period=BATCH_PERIOD)
        self.web = WebViewerServer(cfg.grpc_port, cfg.web_port) if cfg.serve_web else None
        urls = [u for u in (cfg.connect_url, self.web and self.web.grpc_url) if u]
        try:
            self.rec.set_outputs(FilePath(cfg.record_path).expanduser() if cfg.record_path
                                 else None, urls, footer=False)
        except Exception:
            self.close()
            raise
        self._throttle = WarnThrottle(self.get_logger().warning)
        metrics = LiveMetrics(self.rec, cfg.robot_radius,
                              world.density if world is not None else None, self._warn,
                              world.metric if world is not None else None)
        self.team = LiveTeam(self.rec, cfg.rates(), metrics)
        if cfg.explore and world is not None:
            from coverage_ros.viz.live_exploration import ExplorationLayer

            self.team.set_map(world.grid)  # no /map when exploring: the truth, for reference
            self.team.exploration = ExplorationLayer(self.rec, world.grid, world.solid,
                                                     cfg.robot_radius)
        self.subs: dict[int, dict] = {}  # robot id -> {topic kind: Subscription}
        self._idle: dict[int, int] = {}  # robot id -> graph looks without a publisher
        self._scanned: set[int] = set()  # robots whose first scan was logged
        self.create_subscription(Clock, "/clock", self._guard("/clock", self._on_clock),
                                 CLOCK_QOS)
        self.create_subscription(OccupancyGrid, "/map", self._guard("/map", self._on_map),
                                 MAP_QOS)
        self.create_subscription(WorldStatus, "/world/robots",
                                 self._guard("/world/robots", self._on_status), TEAM_QOS)
        self.create_timer(DISCOVERY_PERIOD, self._discover,
                          clock=RclClock(clock_type=ClockType.STEADY_TIME))
        self.regions = RegionInput(self, self._on_region, self._warn)
        outputs = [f"{what} {where}" for what, where in (
            ("file", cfg.record_path), ("viewer", cfg.connect_url),
            ("web viewer", self.web and self.web.web_url)) if where]
        self.get_logger().info(f"recording {self.rec.recording_id} to {', '.join(outputs)}")
        self._discover()

    # ------------------------------------------------------------------ helpers
    def _warn(self, key: str, text: str) -> None:
        self._throttle.warn(key, text)

    def _guard(self, what: str, callback, *args):
        """``callback(*args, msg)``; a bad message is dropped with a throttled warning."""
        def run(msg) -> None:
            try:
                callback(*args, msg)
            except Exception as exc:  # a viewer never crashes on input
                self._warn(what, f"dropped a message on {what}: {exc}")
        return run

    @staticmethod
    def _map_frame(header) -> float:
        """[s] stamp of a header in the map frame ('' counts as map); ValueError otherwise."""
        if header.frame_id not in (conv.MAP_FRAME, ""):
            raise ValueError(f"frame_id {header.frame_id!r}, expected {conv.MAP_FRAME!r}")
        return conv.from_time_msg(header.stamp)

    # ------------------------------------------------------------------ robots in the graph
    def _discover(self) -> None:
        found: dict[int, set[str]] = {}
        for rid, kind, topic, types in robot_topic_kinds(self.get_topic_names_and_types(),
                                                         self.config.robot_prefix):
            if kind not in TOPICS:
                continue
            expected = type_name(TOPICS[kind][0])
            if expected not in types:
                self._warn(topic, f"not subscribing {topic}: type {types}, expected {expected}")
            elif self.count_publishers(topic) > 0:
                found.setdefault(rid, set()).add(kind)
        for robot_id, kinds in found.items():
            if robot_id not in self.subs:
                self.subs[robot_id] = {}
                self.team.add_robot(robot_id)
                self.get_logger().info(f"robot {robot_id} joined")
            self._idle[robot_id] = 0
            subs = self.subs[robot_id]
            for kind in sorted(kinds - subs.keys()):
                msg_type, qos = TOPICS[kind]
                topic = f"/{self.config.robot_prefix}{robot_id}/{kind}"
                subs[kind] = self.create_subscription(
                    msg_type, topic, self._guard(topic, getattr(self, f"_on_{kind}"), robot_id),
                    qos, event_callbacks=quiet_subscription())
        for robot_id in [r for r in self.subs if r not in found]:
            self._idle[robot_id] += 1
            if self._idle[robot_id] >= VANISH_CHECKS:
                for sub in self.subs.pop(robot_id).values():
                    self.destroy_subscription(sub)
                self.team.remove_robot(robot_id)
                self._scanned.discard(robot_id)
                self.get_logger().info(f"robot {robot_id} left")

    # ------------------------------------------------------------------ global topics
    def _on_region(self, region) -> None:
        self.rec.set_time(self.team.now)
        self.rec.log_region(region.polygons)

    def _on_clock(self, msg: Clock) -> None:
        self.team.advance(conv.from_time_msg(msg.clock))

    def _on_map(self, msg: OccupancyGrid) -> None:
        self._map_frame(msg.header)
        grid = conv.occupancy_grid_to_grid(msg)
        if self.team.set_map(grid):
            self.get_logger().info(f"map {grid.width} x {grid.height} at {grid.resolution:g} m")

    def _on_status(self, msg: WorldStatus) -> None:
        t = conv.from_time_msg(msg.header.stamp)
        self.team.status("world", t, {"sim_time": t, "real_time_factor": msg.real_time_factor,
                                      "robots": float(len(msg.robots)),
                                      "steps": float(msg.steps)})
        for rid, values in conv.world_status_robots(msg).items():
            self.team.status(f"robot_{rid}", t, {k: v for k, v in values.items()
                                                 if k not in STATUS_SKIP and math.isfinite(v)})

    # ------------------------------------------------------------------ per-robot topics
    def _on_ground_truth(self, robot_id: int, msg: Odometry) -> None:
        view = self.team.robots.get(robot_id)
        first = view is not None and view.poses.latest_time is None
        t, pose = self._map_frame(msg.header), conv.odometry_to_pose(msg)
        self.team.pose(robot_id, t, pose)
        if first:  # "joined" said its topics exist; this says it is on the map now
            self.get_logger().info(f"robot {robot_id}: first pose ({pose[0]:.2f}, {pose[1]:.2f}) "
                                   f"at t={t:.2f} s")

    def _on_scan(self, robot_id: int, msg: LaserScan) -> None:
        # The scan frame is the robot's body frame (lidar at the centre, x forward).
        t = conv.from_time_msg(msg.header.stamp)
        if robot_id not in self._scanned:
            self._scanned.add(robot_id)
            self.get_logger().info(f"robot {robot_id}: first scan at t={t:.2f} s")
        if not self.team.scan(robot_id, t, lambda pose: conv.scan_to_points(msg, pose)):
            self._warn(f"scanpose{robot_id}", f"robot {robot_id}: scan at t={t:.2f} s dropped: "
                       "no ground_truth pose near that time")

    def _on_goal_pose(self, robot_id: int, msg: PoseStamped) -> None:
        x, y, _ = conv.pose_stamped_to_pose(msg)
        self.team.goal(robot_id, self._map_frame(msg.header), (x, y))

    def _on_plan(self, robot_id: int, msg: Path) -> None:
        self.team.plan(robot_id, self._map_frame(msg.header), conv.path_to_points(msg))

    def _on_cell(self, robot_id: int, msg: OccupancyGrid) -> None:
        self.team.cell(robot_id, self._map_frame(msg.header), conv.cell_grid_to_grid(msg))

    def _on_cell_polygon(self, robot_id: int, msg: PolygonStamped) -> None:
        self.team.polygon(robot_id, self._map_frame(msg.header), conv.polygon_to_points(msg))

    def _on_observations(self, robot_id: int, msg: PointCloud2) -> None:
        layer = self.team.exploration
        if layer is not None:
            evidence = conv.evidence_from_msg(msg, robot_id, layer.lattice)
            self.team.observations(robot_id, self._map_frame(msg.header), evidence)

    def _on_coverage_state(self, robot_id: int, msg: RobotState) -> None:
        values = conv.coverage_state_values(msg)  # checks the map frame
        self.team.state(robot_id, conv.from_time_msg(msg.header.stamp), values)

    # ------------------------------------------------------------------ shutdown
    def close(self) -> None:
        """Finish pending work, then flush and close every output (a complete .rrd)."""
        team = getattr(self, "team", None)
        if team is not None and team.metrics is not None:
            team.metrics.close()
        try:
            self.rec.close()
        except Exception as exc:  # a viewer that went away must not cost the file
            print(f"rerun_bridge: warning: {exc}", file=sys.stderr)
        finally:
            if self.web is not None:
                self.web.stop()


def _close(node: RerunBridge) -> None:
    node.close()
    if node.config.record_path:
        path = FilePath(node.config.record_path).expanduser()
        if node.config.record_index:
            from coverage_ros.viz.recording import index_recording

            problem = index_recording(path)
            if problem is not None:
                print(f"rerun_bridge: warning: {problem}", file=sys.stderr)
        print(f"rerun_bridge: wrote {path}", file=sys.stderr)


def main(args=None) -> int:
    # The file is written without rerun's in-memory chunk index (indexed at the end instead):
    # rerun's warning about that, once per run, would only alarm (set before rerun loads).
    os.environ.setdefault("RUST_LOG", "warn,re_log_encoding::rrd::file_sink=error")
    return run_node("rerun_bridge", RerunBridge, args, cleanup=_close, parameters=PARAMETERS)


if __name__ == "__main__":
    sys.exit(main())
