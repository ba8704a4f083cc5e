"""The region of interest as every node of a team takes it (README "Using it on your robots").

A node may start with a region (robot_node's ``region`` parameter). ``/coverage/region``
(``geometry_msgs/PolygonStamped``, ``map`` frame) adds a polygon to the region (one it already
holds changes nothing); a polygon with no points clears it, as does any message on
``/coverage/region/clear`` (``std_msgs/Empty``). The region topic is transient local with a
depth of :data:`REGION_HISTORY`, so a node that starts late still gets the region (clear with an
empty polygon, not the clear topic, when nodes may join later). A malformed polygon is dropped
with a warning and changes nothing.
"""

from __future__ import annotations

from collections.abc import Callable

from geometry_msgs.msg import PolygonStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Empty

from coverage_ros.core.world.region import Region
from coverage_ros.errors import CoverageError
from coverage_ros.nodes import conversions as conv

REGION_TOPIC = "/coverage/region"
CLEAR_TOPIC = "/coverage/region/clear"
REGION_HISTORY = 10
#: [m] a polygon held and one that came back through a message (float32 points) match this well
SAME_POINT = 1e-4
REGION_QOS = QoSProfile(depth=REGION_HISTORY, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)


class RegionInput:
    """Keeps the region from the topics; ``apply(region)`` takes each new one (raising
    CoverageError refuses it: the region stays as it was)."""

    def __init__(self, node: Node, apply: Callable[[Region], None],
                 warn: Callable[[str, str], object], initial: Region | None = None) -> None:
        self.region = initial or Region()
        self._apply, self._warn, self._log = apply, warn, node.get_logger()
        node.create_subscription(PolygonStamped, REGION_TOPIC, self._on_polygon, REGION_QOS)
        node.create_subscription(Empty, CLEAR_TOPIC, lambda _: self._set(Region(), "cleared"),
                                 10)

    def _on_polygon(self, msg: PolygonStamped) -> None:
        if msg.header.frame_id not in (conv.MAP_FRAME, ""):
            self._warn("region", f"dropped a polygon on {REGION_TOPIC}: frame_id "
                       f"{msg.header.frame_id!r}, expected {conv.MAP_FRAME!r}")
            return
        points = conv.polygon_to_points(msg)
        if len(points) == 0:
            self._set(Region(), "cleared")
            return
        try:
            region = self.region.with_polygon(points)
        except CoverageError as exc:
            self._warn("region", f"dropped a polygon on {REGION_TOPIC}: {exc}")
            return
        if self.region.holds(region.polygons[-1], SAME_POINT):
            return  # held already (e.g. the start region, published for the viewers too)
        self._set(region, "now")

    def _set(self, region: Region, what: str) -> None:
        try:
            self._apply(region)
        except CoverageError as exc:
            self._warn("region", f"dropped the region from {REGION_TOPIC}: {exc}")
            return
        self.region = region
        self._log.info(f"region of interest {what}: {region.describe()}")
