"""When a robot may start: its first coverage update waits until it has listened for its team
(:class:`TeamListening`).

A robot that updates before it knows a teammate standing next to it takes the space of both
as its cell and heads the same way as that teammate: the two end on one side of the map, a
worse local optimum of the coverage cost. So a robot listens for ``first`` seconds (one look
at the ROS graph and the states found), and, when it knows the team's size, until it has heard
every other robot, for at most ``timeout`` seconds.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class TeamListening:
    """Times are [s] on one monotonic clock (wall time: discovery runs on it)."""

    first: float  # listen at least this long after the first pose
    team_size: int = 0  # robots in the team, this one included (0: unknown)
    timeout: float = 10.0  # listen at most this long for a known team
    since: float | None = None  # the first pose
    done: bool = False

    def pose(self, now: float) -> None:
        """The robot knows where it is: listening starts (once)."""
        if self.since is None:
            self.since = now

    def listening(self, now: float, heard: int) -> tuple[bool, str]:
        """``(still listening, warning)``, having heard ``heard`` other robots by ``now``. The
        warning (once, when the timeout ends the wait) says who is missing."""
        if self.done or self.since is None:
            return False, ""
        waited = now - self.since
        missing = self.team_size - 1 - heard
        if waited < self.first or (missing > 0 and waited < self.timeout):
            return True, ""
        self.done = True
        if missing <= 0:
            return False, ""
        return False, (f"heard {heard} of the {self.team_size - 1} other robots (team_size "
                       f"{self.team_size}) in {waited:.1f} s (listen_timeout): starting "
                       "without the others")
