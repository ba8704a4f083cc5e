"""The handover's settings: the geodesic strategy's ``escape_*`` parameters as the protocol
(:mod:`.protocol`) takes them."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class HandoverSettings:
    """The ``escape_*`` settings of the geodesic strategy (validated there)."""

    gain: float  # least saving of the bound, as a share of the pair's cost H_i + H_j
    team_gain: float  # ... and as a share of the H of all the robot hears
    settle: float  # [m] a robot whose Lloyd step is shorter is settled ...
    cooldown: int  # [updates] after a relocation or a dropped claim, before the next claim
    wait: int  # [updates] a claim waits this long for its grant
    transit: int  # [updates] a relocating robot gives up after this many
    steps: int  # Lloyd steps of the split and of the removal
    joint_steps: int = 10  # Lloyd steps of the joint bound
    joint_rings: int = 1  # rings of cells around the pair the joint bound widens to, at most
    #: offers (the largest first) priced by the team's own descent when no bound passes
    descent_offers: int = 0
    #: starts over the cell of each robot offering one of those, for one point per room of it
    #: (:func:`.split.room_offers`) priced by the descent too when none of the offers pays
    descent_rooms: int = 0
    #: [m] longest step of a robot along the descents that price a move (0: whole Lloyd steps)
    descent_step: float = 0.0
    settle_share: float = math.inf  # ... and shorter than this share of its cell's radius
    #: [updates] claims wait until the robot and all it hears have stood within its settle
    #: step for this many updates (0: no wait; :class:`.stillness.TeamStillness`)
    still: int = 0

    def settle_below(self, area: float) -> float:
        """[m] a Lloyd step shorter than this settles a robot whose cell has ``area`` [m^2]."""
        return min(self.settle, self.settle_share * math.sqrt(area / math.pi))
