"""Coverage strategies behind one interface (:class:`Strategy`), selected by name."""

from __future__ import annotations

from typing import Any

from coverage_ros.core.strategies.acvt import AcvtStrategy
from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    Scan,
    SharedState,
    Strategy,
    StrategyContext,
)
from coverage_ros.core.strategies.bvc import BvcStrategy
from coverage_ros.core.strategies.geodesic import GeodesicStrategy
from coverage_ros.core.strategies.lloyd import LloydStrategy
from coverage_ros.core.strategies.tangentbug import TangentBugStrategy
from coverage_ros.errors import ConfigError

STRATEGIES: dict[str, type[Strategy]] = {
    AcvtStrategy.name: AcvtStrategy,
    BvcStrategy.name: BvcStrategy,
    GeodesicStrategy.name: GeodesicStrategy,
    LloydStrategy.name: LloydStrategy,
    TangentBugStrategy.name: TangentBugStrategy,
}


def make_strategy(name: str, context: StrategyContext, **params: Any) -> Strategy:
    """Build a strategy by name (``geodesic``, ``lloyd``, ...)."""
    if name not in STRATEGIES:
        raise ConfigError.at("strategy", "unknown strategy", name, f"one of {sorted(STRATEGIES)}")
    return STRATEGIES[name](context, **params)


__all__ = ["STRATEGIES", "Decision", "Neighbour", "Observation", "Scan", "SharedState",
           "Strategy", "StrategyContext", "make_strategy"]
