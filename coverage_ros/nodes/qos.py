"""The QoS of each kind of topic of the team, and QoS event callbacks left out where they cost.

QoS (one table for the whole team; README "Nodes, topics and parameters" lists it per topic):

* ``MAP_QOS`` - reliable, transient local, depth 1: latched like map_server's ``/map``, so a
  node that starts late still gets the map;
* ``SCAN_QOS`` - rclpy's sensor-data profile (best effort, volatile): compatible with every
  lidar driver, a lost scan is replaced by the next one;
* ``TEAM_QOS`` - reliable, volatile, depth 10: the team's own streams (``coverage_state``,
  ``cmd_vel``, ``goal_pose``, ``plan``, ``cell``, odometry, ``/world/...``);
* ``STREAM_QOS`` - best effort, depth 5: what an observer (the rerun bridge) reads of
  high-rate streams; it matches reliable and best-effort publishers alike;
* ``CLOCK_QOS`` - best effort, depth 1: an observer only needs the newest ``/clock``;
* lock-step (README "Lock-step simulation": nothing the world's barrier waits for may be lost):
  ``TICK_QOS`` (``/world/tick``, scans) reliable, depth 10; ``REPORT_QOS``
  (``/world/tick_report``, every member's answers on one topic) reliable, depth 1000;
  ``LOCKSTEP_STATE_QOS`` (``coverage_state``) reliable and transient local, depth 10, so that a
  robot that subscribes late still gets the states of the ticks it waits for.
"""

from __future__ import annotations

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data

MAP_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
SCAN_QOS = qos_profile_sensor_data
TEAM_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
STREAM_QOS = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
TICK_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
REPORT_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
LOCKSTEP_STATE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.TRANSIENT_LOCAL)


def quiet_publisher() -> PublisherEventCallbacks:
    """``event_callbacks`` for a publisher without rclpy's default QoS event handlers.

    Every handler is a waitable that the Python executor adds to its wait set on every
    wake-up: with a team's dozens of topics per process, most of an idle robot's CPU.
    Incompatible QoS is still reported by the
    subscribing side where it matters (map, pose and scan inputs keep their handlers)."""
    return PublisherEventCallbacks(use_default_callbacks=False)


def quiet_subscription() -> SubscriptionEventCallbacks:
    """``event_callbacks`` for a subscription without the default QoS event handlers (see
    :func:`quiet_publisher`); for topics of the team's own nodes, whose QoS match by design."""
    return SubscriptionEventCallbacks(use_default_callbacks=False)
