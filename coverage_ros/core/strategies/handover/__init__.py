"""Closet escape by handover for the geodesic strategy: a robot leaves a small cell for a
neighbour's larger one when a pairwise bound, or a joint one with the neighbours of both cells
re-spreading, says H drops (:mod:`.bounds`), after a claim the neighbour grants
(:mod:`.protocol`)."""

from coverage_ros.core.strategies.handover.bounds import (
    Known,
    Removal,
    joint_change,
    known_cells,
    removal_increase,
)
from coverage_ros.core.strategies.handover.protocol import Handover, HandoverStep
from coverage_ros.core.strategies.handover.settings import HandoverSettings
from coverage_ros.core.strategies.handover.split import (
    SplitOffer,
    room_offers,
    split_offer,
    split_offers,
)

__all__ = ["Handover", "HandoverSettings", "HandoverStep", "Known", "Removal", "SplitOffer",
           "joint_change", "known_cells", "removal_increase", "room_offers", "split_offer",
           "split_offers"]
