"""Relocation plans that name several robots, carried in the coverage state.

An exchange or a swap (:mod:`.exchange`) moves several robots at once; if each of them predicted
it on its own, live positions that differ by a few centimetres between robots could make them
predict different moves and carry out half of one. So in a team of mixed reaches one robot of a
neighbourhood - the one of lowest id it hears - predicts, and publishes the plan among its
state's extras: ``plan_from`` (its id), ``plan_seq`` (its plan count) and ``plan_<id>_x``,
``plan_<id>_y`` [m] for every robot named. A named robot that hears a plan it has not carried
out yet drives to its point.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from coverage_ros.core.strategies.base import SharedState

PLAN_FROM, PLAN_SEQ = "plan_from", "plan_seq"


def plan_extras(planner: int, seq: int, points: dict[int, np.ndarray]) -> dict[str, float]:
    """The extras that publish plan ``seq`` of robot ``planner``: robot id -> ``(2,)`` point.

    >>> sorted(plan_extras(0, 1, {3: np.array([1.0, 2.0])}).items())
    [('plan_3_x', 1.0), ('plan_3_y', 2.0), ('plan_from', 0.0), ('plan_seq', 1.0)]
    """
    out = {PLAN_FROM: float(planner), PLAN_SEQ: float(seq)}
    for rid, (x, y) in points.items():
        out[f"plan_{rid}_x"], out[f"plan_{rid}_y"] = float(x), float(y)
    return out


def heard_plan(robot_id: int, states: Iterable[SharedState | None]
               ) -> tuple[tuple[int, int], np.ndarray] | None:
    """The first plan among ``states`` that names ``robot_id``: ``((planner, seq), point)``;
    None if none does (or its values are not finite)."""
    for st in states:
        if st is None:
            continue
        ex = st.extra
        x, y = ex.get(f"plan_{robot_id}_x"), ex.get(f"plan_{robot_id}_y")
        planner, seq = ex.get(PLAN_FROM), ex.get(PLAN_SEQ)
        if x is None or y is None or planner is None or seq is None or not all(
                math.isfinite(v) for v in (x, y, planner, seq)):
            continue
        return (int(planner), int(seq)), np.array([x, y], dtype=np.float64)
    return None
