"""Driving a TangentBug heading (:mod:`.bug`): the unicycle command ``(v, w)`` that turns the
robot toward the heading and never drives it farther than it can brake in the free space ahead.

The turn rate is proportional to the heading error, and beyond :data:`TURN_IN_PLACE` the robot
turns in place; the speed is ``v_max cos(error)``, capped by the free length straight ahead at
the robot's radius + :data:`SAFETY_MARGIN` (covered in :data:`BRAKE_TIME`) and, near an
endpoint (a goal or a projection), by :data:`APPROACH_GAIN` times the distance left.
"""

from __future__ import annotations

import math

import numpy as np

from coverage_ros.core.geometry import wrap_angle
from coverage_ros.core.strategies.tangentbug.scan_geometry import free_lengths

#: [rad/s per rad] proportional heading gain (turns half the error per step at 5 Hz).
HEADING_GAIN = 2.5
#: [rad] heading errors beyond this are corrected by turning in place.
TURN_IN_PLACE = math.radians(60.0)
#: [s] the robot may drive at most its free length (at the physical safety radius) in this time.
BRAKE_TIME = 1.0
#: [1/s] approach speed per metre to an endpoint (goal, projection): no overshoot at 5 Hz.
APPROACH_GAIN = 1.0
#: [m] physical margin added to the robot radius for the brake (stops short of contact).
SAFETY_MARGIN = 0.02


def steer(yaw: float, heading: float, rel: np.ndarray, reach: float, approach: float | None,
          v_max: float, w_max: float, robot_radius: float, lookahead: float
          ) -> tuple[float, float]:
    """``(v [m/s], w [rad/s])`` from ``yaw`` toward ``heading`` [rad] (map frame) with the scan
    returns ``rel (M, 2)`` [m] relative to the robot; the brake looks ``max(reach, lookahead)``
    [m] ahead; ``approach`` [m]: the distance left to an endpoint, if heading for one."""
    err = float(wrap_angle(heading - yaw))
    w = float(np.clip(HEADING_GAIN * err, -w_max, w_max))
    v = 0.0 if abs(err) > TURN_IN_PLACE else v_max * math.cos(err)
    ahead = np.array([[math.cos(yaw), math.sin(yaw)]])
    room = float(free_lengths(rel, ahead, robot_radius + SAFETY_MARGIN,
                              max(reach, lookahead))[0])
    v = min(v, room / BRAKE_TIME)
    if approach is not None:
        v = min(v, APPROACH_GAIN * approach)
    return max(v, 0.0), w
