"""Getting unstuck: a robot whose safety filter has held it still for ``STUCK_TIME`` while it
wanted to drive backs off from what blocks it, then plans again.

A path is planned on the configuration space's cell centres, which lets it pass a real
obstacle's corner a centimetre or two closer than the lidar check allows (a rotated table's
corner rasterizes inside the true one): the filter stops the robot there for good. Like a
navigation stack's recovery behaviours, :class:`StuckRecovery` then drives
``ESCAPE_DISTANCE`` away from the obstacle points around the robot (forward or backward,
whichever needs less turning; the safety filter still checks every command, and lets a robot
move away from what it is near), and asks for a new path from there.

Only a blocked wanted motion counts: a robot standing at its goal, paused or driven by a person
never escapes. A robot held by a neighbour ("robot ahead") waits longer, ``GIVE_WAY_TIME``, for
it to pass, then *gives way*: it drives ``GIVE_WAY_DISTANCE`` to the right of its way and plans
again. Two robots that meet head-on on one line (robots relocating between targets, a team
crossing itself) otherwise wait for each other for ever - each holds the other's arc blocked;
stepping to their own right, both clear the line, as people passing in a corridor do.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from coverage_ros.core.geometry import wrap_angle

#: [s] held still by a wall or an obstacle this long while wanting to drive: escape.
STUCK_TIME = 2.0
#: [m] how far an escape drives from where it began.
ESCAPE_DISTANCE = 0.12
#: [s] an escape gives up after this long (the filter may hold it too).
ESCAPE_TIME = 4.0
#: Share of v_max an escape drives at.
ESCAPE_SPEED = 0.5
#: [m] obstacle points within this distance decide the way out.
ESCAPE_LOOK = 0.4
#: Safety notes that count as blocked by the world (not by a neighbour robot).
BLOCKED_BY = ("wall ahead", "obstacle in scan")
#: The safety note of a neighbour in the way.
ROBOT_AHEAD = "robot ahead"
#: [s] held still by a neighbour this long while wanting to drive: give way to the right.
GIVE_WAY_TIME = 5.0
#: [m] how far giving way drives to the right (two TurtleBot3 bodies and their margin apart:
#: 2 x 0.105 + 0.06 m = 0.27 m of the 0.4 m two robots open up between them).
GIVE_WAY_DISTANCE = 0.2


def away_from(position: np.ndarray, points: np.ndarray) -> float | None:
    """[rad] the direction away from the obstacle ``points (N, 2)`` within ESCAPE_LOOK of
    ``position``, the nearer weighing more (1/d^2); None when none is near or they surround
    the robot evenly."""
    rel = np.asarray(position[:2], dtype=np.float64) - np.asarray(points).reshape(-1, 2)
    d = np.hypot(rel[:, 0], rel[:, 1])
    near = (d <= ESCAPE_LOOK) & (d > 1e-9)
    if not near.any():
        return None
    push = (rel[near] / d[near, None] ** 3).sum(axis=0)
    if float(np.hypot(*push)) < 1e-9:
        return None
    return math.atan2(float(push[1]), float(push[0]))


class StuckRecovery:
    """See module docstring. ``observe`` after every filtered command; ``command`` before."""

    def __init__(self, v_max: float, heading_gain: float, turn_in_place: float) -> None:
        self.v_max = v_max
        self.heading_gain = heading_gain
        self.turn_in_place = turn_in_place
        self.blocked_since: float | None = None
        self.blocked_by = ""  # "world" or "robot": what holds the robot since blocked_since
        #: (start xy, direction [rad], give-up time [s], why, distance [m]) of the running
        #: escape (or giving way).
        self.escape: tuple[np.ndarray, float, float, str, float] | None = None
        self.escapes = 0
        self.give_ways = 0
        #: Why the escape that just ended began (:data:`ROBOT_AHEAD` for giving way): the
        #: caller replans - around the robots in the way after giving way - and clears it.
        self.ended = ""

    def observe(self, wanted_v: float, v: float, note: str, pose: np.ndarray, now: float,
                obstacles: Callable[[], np.ndarray]) -> None:
        """One filtered command: ``wanted_v`` before the safety filter, ``v`` after it, with
        its ``note``; ``obstacles()`` gives the ``(N, 2)`` points around the robot (map
        frame), asked for only when an escape begins."""
        if self.escape is not None:
            return
        held = abs(wanted_v) > 1e-3 and abs(v) < 1e-9
        by = "world" if held and any(b in note for b in BLOCKED_BY) else \
            "robot" if held and ROBOT_AHEAD in note else ""
        if not by:
            self.blocked_since = None
            return
        if self.blocked_since is None or now < self.blocked_since or by != self.blocked_by:
            self.blocked_since, self.blocked_by = now, by
            return
        if now - self.blocked_since < (STUCK_TIME if by == "world" else GIVE_WAY_TIME):
            return
        self.blocked_since = None
        start = np.array(pose[:2], dtype=np.float64)
        if by == "robot":  # to the right of the way it wants to go
            way = pose[2] if wanted_v > 0 else pose[2] + math.pi
            self.escape = (start, float(wrap_angle(way - 0.5 * math.pi)), now + ESCAPE_TIME,
                           ROBOT_AHEAD, GIVE_WAY_DISTANCE)
            self.give_ways += 1
            return
        direction = away_from(pose, obstacles())
        if direction is not None:
            why = note.split(": ", 1)[-1]
            self.escape = (start, direction, now + ESCAPE_TIME, why, ESCAPE_DISTANCE)
            self.escapes += 1

    def command(self, pose: np.ndarray, now: float) -> tuple[float, float] | None:
        """While escaping, the ``(v, w)`` that drives away (before the safety filter); None
        when not escaping (the escape that just ended sets ``ended``)."""
        if self.escape is None:
            return None
        start, direction, until, _, distance = self.escape
        if float(np.hypot(*(pose[:2] - start))) >= distance or not now < until:
            self.ended, self.escape = self.escape[3], None
            return None
        err = float(wrap_angle(direction - pose[2]))
        sign = 1.0
        if abs(err) > 0.5 * math.pi:  # backing out needs less turning
            err, sign = float(wrap_angle(err - math.pi)), -1.0
        w = self.heading_gain * err
        v = 0.0 if abs(err) > self.turn_in_place else sign * ESCAPE_SPEED * self.v_max * \
            math.cos(err)
        return v, w

    def describe(self) -> str:
        """The running escape, '' when none."""
        if self.escape is None:
            return ""
        if self.escape[3] == ROBOT_AHEAD:
            return f"giving way: held still {GIVE_WAY_TIME:g} s by a {ROBOT_AHEAD}"
        return f"escaping: held still {STUCK_TIME:g} s by {self.escape[3]}"
