"""When a team has settled (``coverage-team --until-settled S``): its coverage cost H has stayed
within SETTLED_BAND for the last S seconds of sim time, and no robot has been moving between
cells meanwhile (a closet escape's claim, grant or relocation, an acvt relocation) or waiting
for its first update. A team that settles and then finds a better configuration moves again
before S has passed: S should outlast the pause between its robots settling and the first
claim (a few updates).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from coverage_msgs.msg import RobotState

SETTLED_BAND = 0.01  # H within 1 % (max over min) over the window


def moving_between_cells(msg: RobotState) -> bool:
    """Whether robot state ``msg`` says its robot is in a handover or relocation, or has not
    made a coverage update yet."""
    if msg.mode in (RobotState.MODE_RELOCATE, RobotState.MODE_NONE):
        return True
    if any(h.claim >= 0 or h.grant >= 0 for h in msg.handover):
        return True
    return any(a.relocating for a in msg.acvt)


def h_flat_since(samples: list[tuple[float, float]], now: float, window: float,
                 band: float = SETTLED_BAND) -> bool:
    """Whether the ``(t, H)`` samples cover the last ``window`` [s] before ``now`` (one at or
    before its start) and stayed within ``band`` of each other over it."""
    start = now - window
    before = [k for k, (t, _) in enumerate(samples) if t <= start + 1e-9]
    if not before:
        return False
    hs = [h for _, h in samples[before[-1]:] if h == h]
    return bool(hs) and min(hs) > 0 and max(hs) <= (1.0 + band) * min(hs)


@dataclass
class SettleWatch:
    """Follows the robots' states for ``--until-settled window`` [s of sim time]."""

    window: float
    #: [s] per robot: stamps of its recent states that said it was moving between cells
    moving: dict[int, list[float]] = field(default_factory=dict)
    #: [s] per robot: stamps of the oldest and the newest of its states heard
    first: dict[int, float] = field(default_factory=dict)
    newest: dict[int, float] = field(default_factory=dict)

    def note(self, rid: int, msg: RobotState, stamp: float) -> None:
        """Robot ``rid``'s state, stamped ``stamp`` [s of sim time]."""
        self.first[rid] = min(self.first.get(rid, math.inf), stamp)
        self.newest[rid] = max(self.newest.get(rid, -math.inf), stamp)
        if moving_between_cells(msg):
            self.moving.setdefault(rid, []).append(stamp)

    def heard_up_to(self, rid: int) -> float:
        """[s] stamp of robot ``rid``'s newest state heard (-inf: none)."""
        return self.newest.get(rid, -math.inf)

    def settled(self, samples: list[tuple[float, float]], now: float, robots: list[int],
                upto: float = math.inf) -> bool:
        """Whether the team of ``robots`` (the living) has settled at ``now`` [s], from the
        states stamped up to ``upto`` [s] (lock-step: the tick before, whose states every
        robot has published; later ones may or may not have arrived). A robot with no state
        stamped by then counts as moving now."""
        start = now - self.window
        for stamps in self.moving.values():
            stamps[:] = [s for s in stamps if s > start]  # older moves never count again
        for rid in robots:
            if rid not in self.first or self.first[rid] > upto:
                return False
            if any(s <= upto for s in self.moving.get(rid, ())):
                return False
        return h_flat_since(samples, now, self.window)
