"""What a robot knows of its neighbours: the latest valid state each published
(:class:`NeighbourTable`).

Entries with non-finite values, positions off the map, or older than the timeout are ignored;
a neighbour's state arrives from the ROS executor's thread while the robot's updates read the
table from theirs, so every access takes the table's lock.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.strategies import Neighbour, SharedState
from coverage_ros.core.world.robot import RobotSpec

#: [m] a neighbour may be reported this far outside the map's extent (localisation noise).
MAP_MARGIN = 0.5
#: [s] for the safety filter, a neighbour's position is carried forward by its published
#: velocity (``vx``, ``vy``) over its age, or grown by v_max x its age when it publishes none,
#: up to this age (older ones are stale and dropped by the neighbour timeout anyway; the lidar
#: sees them meanwhile).
MAX_NEIGHBOUR_AGE = 0.5
#: The values every coverage_state carries (from the first pose on, before the first update:
#: only the first three; see README "robot_node").
STATE_KEYS = ("x", "y", "weight", "mass", "cost", "update_ms")


@dataclass
class _Entry:
    state: SharedState
    received: float  # [s] node clock when received


class NeighbourTable:
    """The latest valid state of every other robot, by id."""

    def __init__(self, extent: tuple[float, float, float, float], timeout: float) -> None:
        self.extent = extent
        self.timeout = timeout
        self.entries: dict[int, _Entry] = {}
        self._lock = threading.Lock()

    def receive(self, robot_id: int, values: dict[str, float], now: float,
                parsed: dict[tuple[float, ...], SharedState | str] | None = None) -> str:
        """Store a neighbour's published values; returns "" or why they were rejected.
        ``parsed``, kept by the caller for one message, holds its :func:`parse_state` results
        by map extent: the robots of one process check and build a neighbour's state once."""
        state = None if parsed is None else parsed.get(self.extent)
        if state is None:
            state = parse_state(values, self.extent)
            if parsed is not None:
                parsed[self.extent] = state
        if isinstance(state, str):
            return state
        with self._lock:
            self.entries[robot_id] = _Entry(state, now)
        return ""

    def current(self, now: float, own: np.ndarray | None = None, comm_range: float = 0.0,
                ) -> list[Neighbour]:
        """Fresh neighbours (within ``comm_range`` of ``own`` if that is > 0), by id."""
        with self._lock:
            entries = sorted(self.entries.items())
        out = []
        for rid, e in entries:
            if now - e.received > self.timeout:
                continue
            if comm_range > 0 and own is not None and \
                    float(np.hypot(*(e.state.position - own))) > comm_range:
                continue
            out.append(Neighbour(rid, e.state, e.received))
        return out


def parse_state(values: dict[str, float], extent: tuple[float, float, float, float]
                ) -> SharedState | str:
    """A neighbour's published ``values`` as a state, or why they are rejected (non-finite
    position, weight, mass or cost; a position off the map's ``extent`` beyond MAP_MARGIN; a
    negative weight). A state is never changed once made, so robots may share one."""
    for key, v in values.items():
        if key in STATE_KEYS[:4] and not math.isfinite(v):
            return f"{key} is {v!r}"
    x, y = values["x"], values["y"]
    xmin, ymin, xmax, ymax = extent
    if not (xmin - MAP_MARGIN <= x <= xmax + MAP_MARGIN
            and ymin - MAP_MARGIN <= y <= ymax + MAP_MARGIN):
        return f"position ({x:.2f}, {y:.2f}) is outside the map"
    weight = values.get("weight", 0.0)
    if weight < 0:
        return f"weight {weight!r} < 0"
    virtual = None
    if "virtual_x" in values and "virtual_y" in values:
        virtual = np.array([values["virtual_x"], values["virtual_y"]])
        if not np.all(np.isfinite(virtual)):
            virtual = None
    extra = {k: v for k, v in values.items()
             if k not in STATE_KEYS and k not in ("virtual_x", "virtual_y")}
    mass = values.get("mass")
    position = np.array([x, y])
    for a in (position, virtual):  # (shared: read-only)
        if a is not None:
            a.flags.writeable = False
    return SharedState(position=position, weight=weight,
                       mass=mass if mass is not None and math.isfinite(mass) else None,
                       virtual=virtual, extra=extra)


def safety_discs(neighbours: list[Neighbour], now: float,
                 own: RobotSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The neighbours for the safety filter: ``(N, 2)`` positions now, ``(N,)`` radii and
    ``(N, 2)`` velocities [m/s] (NaN where unpublished). A neighbour may have moved since it
    published: carried forward by its velocity and grown by what a change of speed at ``own``
    a_max can have made of it, else grown by how far it can have gone. Radius and v_max are its
    own when it publishes them, ``own``'s otherwise."""
    nan = math.nan
    rows = [(n.stamp, e.get("radius", own.radius), e.get("v_max", own.v_max), e.get("vx", nan),
             e.get("vy", nan)) for n in neighbours for e in (n.state.extra,)]
    positions = np.array([n.position for n in neighbours], dtype=np.float64).reshape(-1, 2)
    table = np.array(rows, dtype=np.float64).reshape(-1, 5)
    age = np.clip(now - table[:, 0], 0.0, MAX_NEIGHBOUR_AGE)
    radius, v_max, velocities = table[:, 1], table[:, 2], table[:, 3:5].copy()
    moving = np.isfinite(velocities).all(axis=1)
    positions[moving] += velocities[moving] * age[moving, None]
    velocities[~moving] = nan
    grown = np.where(moving, np.minimum(v_max * age, 0.5 * own.a_max * age * age), v_max * age)
    radii = radius + grown
    return positions, radii, velocities
