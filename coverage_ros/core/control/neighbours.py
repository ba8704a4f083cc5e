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

#: [m] a neighbour may be reported this far outside the map's extent (localisation noise).
MAP_MARGIN = 0.5
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

    def receive(self, robot_id: int, values: dict[str, float], now: float) -> str:
        """Store a neighbour's published values; returns "" or why they were rejected."""
        for key, v in values.items():
            if key in STATE_KEYS[:4] and not math.isfinite(v):
                return f"{key} is {v!r}"
        x, y = values["x"], values["y"]
        xmin, ymin, xmax, ymax = self.extent
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
        entry = _Entry(SharedState(
            position=np.array([x, y]), weight=weight,
            mass=mass if mass is not None and math.isfinite(mass) else None,
            virtual=virtual, extra=extra), now)
        with self._lock:
            self.entries[robot_id] = entry
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

