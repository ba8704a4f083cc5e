"""A second simulation on the same ROS domain, noticed from ``/clock`` (:class:`ClockGuard`)."""

from __future__ import annotations

import math


class ClockGuard:
    """Notices a second simulation on the same ROS domain - more than one ``/clock``
    publisher, or sim time going back by more than ``jump_back`` seconds - so that a node says
    so and stops instead of silently mixing two teams (README "Reliability"). Each check
    returns an error text, or '' when all is well."""

    def __init__(self, jump_back: float = 1.0) -> None:
        self.jump_back = jump_back
        self.latest = -math.inf  # [s] newest sim time seen

    def check_time(self, now: float) -> str:
        if now < self.latest - self.jump_back:
            return (f"the clock went back from {self.latest:.1f} s to {now:.1f} s: another "
                    "simulation (or a restarted one) publishes /clock on this ROS_DOMAIN_ID")
        self.latest = max(self.latest, now)
        return ""

    @staticmethod
    def check_publishers(count: int) -> str:
        if count > 1:
            return (f"{count} nodes publish /clock: a second simulation runs on this "
                    "ROS_DOMAIN_ID")
        return ""
