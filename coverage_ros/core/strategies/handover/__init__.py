"""Closet escape by handover for the geodesic strategy: a robot leaves a small cell for a
neighbour's larger one when a pairwise bound says H drops (:mod:`.bounds`), after a claim the
neighbour grants (:mod:`.protocol`)."""

from coverage_ros.core.strategies.handover.bounds import (
    Removal,
    SplitOffer,
    removal_increase,
    split_offer,
)
from coverage_ros.core.strategies.handover.protocol import Handover, HandoverSettings, HandoverStep

__all__ = ["Handover", "HandoverSettings", "HandoverStep", "Removal", "SplitOffer",
           "removal_increase", "split_offer"]
