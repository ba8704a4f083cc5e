"""The named values a robot publishes as its coverage state, which its neighbours read back
(:func:`~coverage_ros.core.control.neighbours.parse_state`): after an update
(:func:`after_update`), before its first one (:func:`before_update`), and the velocity of the
last command it sent (:func:`motion`).
"""

from __future__ import annotations

import math

import numpy as np

from coverage_ros.core.strategies import Decision, SharedState
from coverage_ros.core.strategies.base import mode_code
from coverage_ros.core.world.robot import RobotSpec


def after_update(decision: Decision, robot: RobotSpec, update_ms: float, manual: bool,
                 paused: bool) -> dict[str, float]:
    """Position, weight, mass, cost, the update's duration [ms], body, speed limit, whether
    driven by a person or paused, the mode's code; the virtual generator, if any, and the
    strategy's own values."""
    shared = decision.shared
    state = {"x": float(shared.position[0]), "y": float(shared.position[1]),
             "weight": float(shared.weight), "mass": float(decision.mass),
             "cost": float(decision.cost), "update_ms": update_ms,
             "radius": float(robot.radius), "v_max": float(robot.v_max),
             "manual": float(manual), "paused": float(paused),
             "mode": float(mode_code(decision.mode))}
    if shared.virtual is not None:
        state["virtual_x"], state["virtual_y"] = (float(v) for v in shared.virtual)
    state.update({k: float(v) for k, v in shared.extra.items()})
    return state


def before_update(pose: np.ndarray, robot: RobotSpec, first: SharedState) -> dict[str, float]:
    """Who and where the robot is and its strategy's ``first`` extras (acvt's ``dropout``:
    neighbours wait for its mass), without a cell (no mass or cost yet)."""
    x, y = (float(v) for v in pose[:2])
    return {"x": x, "y": y, "weight": float(robot.power_weight), "radius": float(robot.radius),
            "v_max": float(robot.v_max), **{k: float(v) for k, v in first.extra.items()}}


def motion(sent: tuple[float, float] | None, pose: np.ndarray | None) -> dict[str, float]:
    """``vx``, ``vy`` [m/s] (map frame): the velocity of the last command ``sent (v, w)`` at
    ``pose``'s heading, for the neighbours' safety filters; empty before the first command."""
    if sent is None or pose is None:
        return {}
    v, yaw = sent[0], float(pose[2])
    return {"vx": v * math.cos(yaw), "vy": v * math.sin(yaw)}
