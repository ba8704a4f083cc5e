"""What a robot of the closet escape publishes (``SharedState.extra``, the ``HandoverState`` of
its coverage state) and how its neighbours read it.

A relocating robot publishes where it is going (``relocating``, ``to_x``, ``to_y``); its
neighbours keep its generator where it stood when they first heard it relocating
(:func:`held`) until it has arrived, so that nobody spreads into the cell it leaves meanwhile:
every price of a move (:mod:`.bounds`) is of the team re-spreading from the robot at its point,
which is where the team then descends from. Spreading during the drive, around a robot that
cannot shift along until it arrives, ends elsewhere (often above where the robot left from).
Whoever makes way for it reads where it is going (:func:`destination`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.strategies.base import Neighbour

NONE = -1.0  # published for "no robot" in claim and grant


def value(n: Neighbour, key: str, default: float = 0.0) -> float:
    """A neighbour's published value ``key`` (``default`` when it published none)."""
    v = n.state.extra.get(key, default)
    return float(v) if v is not None else default


def idle() -> dict[str, float]:
    """What a robot publishes that neither offers, claims, grants nor relocates."""
    return {"settled": 0.0, "claim": NONE, "claim_gain": 0.0, "grant": NONE,
            "offer_gain": 0.0, "offer_x": 0.0, "offer_y": 0.0, "offer_base": 0.0,
            "offer2_gain": 0.0, "offer2_x": 0.0, "offer2_y": 0.0,
            "relocating": 0.0, "to_x": 0.0, "to_y": 0.0}


def held(n: Neighbour, origins: dict[int, np.ndarray], resolution: float
         ) -> tuple[np.ndarray, bool]:
    """(2,) [m] where ``n``'s generator counts in its neighbours' cells - while it relocates,
    where it stood when first heard relocating (kept in ``origins`` by robot id), else its
    position - and whether it has just arrived more than ``resolution`` [m] from there."""
    if value(n, "relocating") > 0:
        return origins.setdefault(n.robot_id, np.array(n.position, dtype=np.float64)), False
    origin = origins.pop(n.robot_id, None)
    moved = origin is not None and float(np.hypot(*(n.position - origin))) > resolution
    return n.position, moved


def destination(n: Neighbour) -> np.ndarray:
    """(2,) [m] where ``n`` is heading: its relocation point while it relocates (and published
    a finite one), else its position."""
    if value(n, "relocating") > 0:
        to = np.array([value(n, "to_x", math.nan), value(n, "to_y", math.nan)])
        if np.all(np.isfinite(to)):
            return to
    return n.position


@dataclass(frozen=True)
class Offer:
    """One split a neighbour offers (its first or its second: ``key`` (robot id, 0 or 1))."""

    key: tuple[int, int]
    gain: float  # units of H
    point: np.ndarray  # (2,) [m]
    base: float  # the offering robot's cell cost

    @property
    def robot_id(self) -> int:
        return self.key[0]


def offers_of(n: Neighbour) -> list[Offer]:
    """The splits neighbour ``n`` offers (a saving > 0 at a finite point)."""
    out = []
    for k, prefix in enumerate(("offer", "offer2")):
        gain = value(n, f"{prefix}_gain")
        point = np.array([value(n, f"{prefix}_x", math.nan), value(n, f"{prefix}_y", math.nan)])
        if gain > 0 and np.all(np.isfinite(point)):
            out.append(Offer((n.robot_id, k), gain, point, value(n, "offer_base")))
    return out


def rank(robot_id: int, cost: float, neighbours: Sequence[Neighbour]) -> int:
    """How many robots it hears published a cell cost below the own (then a lower id): its
    turn to price offers by the descent in a settled configuration (module docstring)."""
    return sum((value(n, "offer_base"), n.robot_id) < (cost, robot_id) for n in neighbours
               if value(n, "offer_gain") > 0)

