"""Message conversions: a robot's coverage state (``coverage_msgs/RobotState``) and the world's
status (``coverage_msgs/WorldStatus``) (conventions: :mod:`..conversions`).

Inside the stack a coverage state is the mapping of named values the strategies and the
neighbour table use (:func:`~coverage_ros.core.control.neighbours.parse_state`): ``x``, ``y``,
``weight``, ``radius``, ``v_max``, from the first update on ``mass``, ``cost``, ``update_ms``,
``mode``, ``manual``, ``paused``, when known ``vx``, ``vy``, and each strategy's own values
(tangentbug's ``virtual_x`` ... ``converged``, acvt's ``reach`` ... ``plan_<id>_x``, an explorer's
``greedy``); the message carries each in a typed field. Values a message does not carry (NaN,
an absent strategy entry) are absent from the mapping.
"""

from __future__ import annotations

import math
from typing import Any

from builtin_interfaces.msg import Time
from coverage_msgs.msg import (
    AcvtState,
    ExploreState,
    HandoverState,
    RobotState,
    SimulatedRobot,
    TangentBugState,
    WorldStatus,
)

from coverage_ros.core.lockstep.inbox import EVIDENCE_KEY
from coverage_ros.core.strategies.base import MODES, mode_code
from coverage_ros.nodes.conversions.basics import MAP_FRAME, from_time_msg, to_time_msg

#: Values every state carries in its own fields (the rest: the strategies').
_COMMON = ("x", "y", "weight", "radius", "v_max", "vx", "vy", "mass", "cost", "update_ms",
           "mode", "manual", "paused", "robot_id", EVIDENCE_KEY)
_TANGENTBUG = ("virtual_x", "virtual_y", "cost_real", "cost_virtual", "converged")
_ACVT = ("reach", "dropout", "iteration", "greedy", "settled", "relocating", "plan_from",
         "plan_seq")
_HANDOVER = ("settled", "offer_gain", "offer_x", "offer_y", "offer_base", "offer2_gain",
             "offer2_x", "offer2_y", "claim", "claim_gain", "grant", "relocating", "to_x", "to_y")
NAN = math.nan


def _f(values: dict[str, float], key: str) -> float:
    return float(values.get(key, NAN))


def coverage_state_msg(stamp: Time, values: dict[str, float], frame_id: str = MAP_FRAME,
                       robot_id: int = -1) -> RobotState:
    """``coverage_state`` of robot ``robot_id`` from its named values (module docstring)."""
    msg = RobotState()
    msg.header.stamp, msg.header.frame_id = stamp, frame_id
    msg.robot_id = int(robot_id)
    for key in ("x", "y", "radius", "v_max", "vx", "vy", "mass", "cost", "update_ms"):
        setattr(msg, key, _f(values, key))
    msg.weight = float(values.get("weight", 0.0))  # (none: plain Voronoi cells)
    code = values.get("mode")
    msg.mode = RobotState.MODE_NONE if code is None else \
        int(code) if 0 <= code < len(MODES) else RobotState.MODE_OTHER
    msg.manual, msg.paused = bool(values.get("manual", 0.0)), bool(values.get("paused", 0.0))
    used = set(_COMMON)
    if "cost_real" in values or "virtual_x" in values:
        msg.tangentbug = [TangentBugState(
            virtual_x=_f(values, "virtual_x"), virtual_y=_f(values, "virtual_y"),
            cost_real=_f(values, "cost_real"), cost_virtual=_f(values, "cost_virtual"),
            converged=bool(values.get("converged", 0.0)))]
        used |= set(_TANGENTBUG)
    if "reach" in values:
        plan = sorted(int(k.split("_")[1]) for k in values
                      if k.startswith("plan_") and k.endswith("_x") and k[5:-2].isdigit())
        msg.acvt = [AcvtState(
            reach=_f(values, "reach"), dropout=bool(values.get("dropout", 0.0)),
            iteration=int(values.get("iteration", 0.0)), greedy=bool(values.get("greedy", 0.0)),
            settled=bool(values.get("settled", 0.0)),
            relocating=bool(values.get("relocating", 0.0)),
            plan_from=int(values.get("plan_from", -1.0)), plan_seq=int(values.get("plan_seq", 0)),
            plan_ids=plan, plan_x=[float(values[f"plan_{i}_x"]) for i in plan],
            plan_y=[float(values[f"plan_{i}_y"]) for i in plan])]
        used |= set(_ACVT) | {f"plan_{i}_{c}" for i in plan for c in "xy"}
    elif "greedy" in values:
        msg.explore = [ExploreState(greedy=bool(values["greedy"]))]
        used.add("greedy")
    if "offer_gain" in values:
        msg.handover = [HandoverState(
            settled=bool(values.get("settled", 0.0)), offer_gain=_f(values, "offer_gain"),
            offer_x=_f(values, "offer_x"), offer_y=_f(values, "offer_y"),
            offer_base=_f(values, "offer_base"),
            offer2_gain=float(values.get("offer2_gain", 0.0)), offer2_x=_f(values, "offer2_x"),
            offer2_y=_f(values, "offer2_y"), claim=int(values.get("claim", -1.0)),
            claim_gain=_f(values, "claim_gain"), grant=int(values.get("grant", -1.0)),
            relocating=bool(values.get("relocating", 0.0)), to_x=_f(values, "to_x"),
            to_y=_f(values, "to_y"))]
        used |= set(_HANDOVER)
    rest = sorted(k for k in values if k not in used)
    msg.extra_names = rest
    msg.extra_values = [float(values[k]) for k in rest]
    if EVIDENCE_KEY in values:
        msg.evidence_stamp = to_time_msg(values[EVIDENCE_KEY])
    return msg


def coverage_state_values(msg: RobotState, expected_frame: str = MAP_FRAME
                          ) -> dict[str, float]:
    """The named values of a ``coverage_state``; ValueError naming the problem (another frame,
    a position that is not finite, extra names and values of different lengths)."""
    if msg.header.frame_id != expected_frame:
        raise ValueError(f"frame_id {msg.header.frame_id!r}, expected {expected_frame!r}")
    if not (math.isfinite(msg.x) and math.isfinite(msg.y)):
        raise ValueError(f"position ({msg.x}, {msg.y}) is not finite")
    if len(msg.extra_names) != len(msg.extra_values):
        raise ValueError(f"{len(msg.extra_names)} extra names but {len(msg.extra_values)} "
                         "values")
    out: dict[str, float] = {"x": msg.x, "y": msg.y, "weight": msg.weight}
    for key in ("radius", "v_max"):  # (unknown: NaN, or 0 from a sender that left them out)
        value = getattr(msg, key)
        if math.isfinite(value) and value > 0:
            out[key] = value
    for key in ("vx", "vy", "mass", "cost", "update_ms"):
        value = getattr(msg, key)
        if math.isfinite(value):
            out[key] = value
    if msg.mode != RobotState.MODE_NONE:
        out["mode"] = float(msg.mode if msg.mode < len(MODES) else mode_code(""))
        out["manual"], out["paused"] = float(msg.manual), float(msg.paused)
    for t in msg.tangentbug:
        out.update(cost_real=t.cost_real, cost_virtual=t.cost_virtual,
                   converged=float(t.converged))
        if math.isfinite(t.virtual_x) and math.isfinite(t.virtual_y):
            out.update(virtual_x=t.virtual_x, virtual_y=t.virtual_y)
    for a in msg.acvt:
        if not (len(a.plan_ids) == len(a.plan_x) == len(a.plan_y)):
            raise ValueError(f"acvt plan of {len(a.plan_ids)} robots with {len(a.plan_x)} x "
                             f"and {len(a.plan_y)} y")
        out.update(reach=a.reach, dropout=float(a.dropout), iteration=float(a.iteration),
                   greedy=float(a.greedy), settled=float(a.settled),
                   relocating=float(a.relocating))
        if a.plan_from >= 0:
            out.update(plan_from=float(a.plan_from), plan_seq=float(a.plan_seq))
            for i, x, y in zip(a.plan_ids, a.plan_x, a.plan_y, strict=True):
                out[f"plan_{i}_x"], out[f"plan_{i}_y"] = x, y
    for e in msg.explore:
        out["greedy"] = float(e.greedy)
    for h in msg.handover:
        out.update(settled=float(h.settled), offer_gain=h.offer_gain, offer_x=h.offer_x,
                   offer_y=h.offer_y, offer_base=h.offer_base, offer2_gain=h.offer2_gain,
                   offer2_x=h.offer2_x, offer2_y=h.offer2_y, claim=float(h.claim),
                   claim_gain=h.claim_gain, grant=float(h.grant),
                   relocating=float(h.relocating), to_x=h.to_x, to_y=h.to_y)
    out.update(zip(msg.extra_names, msg.extra_values, strict=True))
    stamp = from_time_msg(msg.evidence_stamp)
    if stamp > 0:
        out[EVIDENCE_KEY] = stamp
    return out


# ---------------------------------------------------------------------------- world status
#: SimulatedRobot fields of the body's spec (RobotSpec.numbers() and the lidar's range).
SPEC_FIELDS = ("radius", "v_max", "w_max", "a_max", "alpha_max", "sensor_radius",
               "power_weight", "lidar_range_max")


def world_status_msg(stamp: Time, world: str, rtf: float, steps: int, tick: int,
                     robots: list[dict[str, Any]]) -> WorldStatus:
    """``/world/robots``; ``robots``: one mapping of SimulatedRobot's fields per robot."""
    msg = WorldStatus(world=world, real_time_factor=float(rtf), steps=int(steps),
                      tick=int(tick))
    msg.header.stamp, msg.header.frame_id = stamp, MAP_FRAME
    msg.robots = [SimulatedRobot(**r) for r in robots]
    return msg


def world_status_robots(msg: WorldStatus) -> dict[int, dict[str, float]]:
    """Every robot of a status by id: its fields as floats (``driving``: 1 or 0)."""
    return {r.id: {k: float(getattr(r, k)) for k in SimulatedRobot.get_fields_and_field_types()}
            for r in msg.robots}
