"""Coverage strategies behind one interface (:class:`Strategy`), selected by name.

The registry is the only place that knows the strategies by name: :func:`strategy_choice`
turns a name and a mapping of settings (from node parameters, a command line or YAML) into a
validated :class:`StrategyChoice` once, at that boundary, and :func:`make_strategy` builds a
robot's strategy from it.

==============  ============================================================================
name            method
==============  ============================================================================
``geodesic``    geodesic power Voronoi cells, generalized Lloyd (Bhattacharya et al. 2014)
``lloyd``       Euclidean power Voronoi cells, classic Lloyd (Cortes et al. 2004)
``tangentbug``  Lloyd on virtual generators, TangentBug (Breitenmoser et al. 2010)
``bvc``         buffered Voronoi cells from lidar, guided map (Wang et al. 2024)
``acvt``        adaptive CVT with agent dropout and reinsertion (Lee & Lee 2024)
==============  ============================================================================

Exploring an unknown map (``explore``: the robots start from a belief of p = 0.5 everywhere)
the names mean:

==============  ============================================================================
``geodesic``    entropy-weighted geodesic cells, Lloyd and greedy modes (Bhattacharya et al.
                2014, Sec. 4.2)
``frontier``    the nearest-best frontier, no coordination (explore_lite's baseline)
==============  ============================================================================
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from coverage_ros.core.strategies.acvt.strategy import AcvtStrategy
from coverage_ros.core.strategies.base import (
    Decision,
    Neighbour,
    Observation,
    Scan,
    SharedState,
    Strategy,
    StrategyContext,
    StrategyDetails,
)
from coverage_ros.core.strategies.bvc.strategy import BvcStrategy
from coverage_ros.core.strategies.explore.strategy import ExploreStrategy
from coverage_ros.core.strategies.frontier.strategy import FrontierStrategy
from coverage_ros.core.strategies.geodesic import GeodesicStrategy
from coverage_ros.core.strategies.lloyd import LloydStrategy
from coverage_ros.core.strategies.tangentbug.strategy import TangentBugStrategy
from coverage_ros.errors import ConfigError


def _register(*classes: type[Strategy]) -> dict[str, type[Strategy]]:
    table: dict[str, type[Strategy]] = {}
    for cls in classes:
        if cls.name in table:
            raise ValueError(f"strategy name {cls.name!r} registered twice")
        table[cls.name] = cls
    return table


STRATEGIES: dict[str, type[Strategy]] = _register(
    AcvtStrategy, BvcStrategy, GeodesicStrategy, LloydStrategy, TangentBugStrategy)
#: The strategies of a team exploring an unknown map.
EXPLORERS: dict[str, type[Strategy]] = _register(ExploreStrategy, FrontierStrategy)


@dataclass(frozen=True)
class StrategyChoice:
    """A strategy by name with its validated settings (an instance of its ``Params``)."""

    name: str
    params: Any
    explore: bool = False  # whether the team explores an unknown map

    def __post_init__(self) -> None:
        cls = strategy_class(self.name, self.explore)
        if not isinstance(self.params, cls.Params):
            raise ConfigError.at(f"strategy {self.name}", "settings of the wrong kind",
                                 type(self.params).__name__, cls.Params.__name__)

    @property
    def cls(self) -> type[Strategy]:
        return strategy_class(self.name, self.explore)

    @property
    def needs_scan(self) -> bool:
        return self.cls.needs_scan or self.cls.explores

    @property
    def needs_map(self) -> bool:
        return self.cls.needs_map


def strategy_class(name: str, explore: bool = False) -> type[Strategy]:
    table = EXPLORERS if explore else STRATEGIES
    if name not in table:
        what = "strategy for exploring" if explore else "strategy"
        raise ConfigError.at("strategy", f"unknown {what}", name, f"one of {sorted(table)}")
    return table[name]


def strategy_choice(name: str, values: Mapping[str, Any] | None = None,
                    where: str = "strategy_params", explore: bool = False) -> StrategyChoice:
    """Validate ``values`` (the strategy's settings by name; omitted ones keep their defaults)
    into the strategy's ``Params`` dataclass. Errors name ``where``, the setting and what is
    expected."""
    cls = strategy_class(name, explore)
    values = dict(values or {})
    known = {f.name: f for f in dataclasses.fields(cls.Params)}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ConfigError.at(f"{where}: {name}", "unknown parameters", unknown,
                             f"some of {sorted(known)}" if known else "none")
    for key, value in values.items():
        _check_type(f"{where}: {name}.{key}", value, known[key].type)
    try:
        params = cls.Params(**values)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    return StrategyChoice(name, params, explore)


def _check_type(where: str, value: Any, annotation: Any) -> None:
    """Refuse a value of the wrong YAML type for a ``Params`` field annotated (as a string,
    the modules use postponed annotations) ``bool``, ``int``, ``float``, ``str``, ``bool | str``
    (true, false or a word the dataclass checks, e.g. ``auto``) or ``... | None``."""
    text = str(annotation).replace(" ", "")
    options = set(text.split("|"))
    if value is None:
        if "None" not in options:
            raise ConfigError.at(where, "must not be empty", value)
        return
    if "bool" in options:
        if not isinstance(value, bool) and not ("str" in options and isinstance(value, str)):
            raise ConfigError.at(where, "must be true or false", value)
        return
    if options & {"float", "int"}:
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(
                value):
            raise ConfigError.at(where, "must be a finite number", value)
        if "float" not in options and not isinstance(value, int):
            raise ConfigError.at(where, "must be an integer", value)
        return
    if "str" in options and not isinstance(value, str):
        raise ConfigError.at(where, "must be a string", value)


def make_strategy(choice: StrategyChoice | str, context: StrategyContext) -> Strategy:
    """Build one robot's strategy (a plain name: its default settings)."""
    if isinstance(choice, str):
        choice = strategy_choice(choice)
    return choice.cls(context, choice.params)


__all__ = ["EXPLORERS", "STRATEGIES", "Decision", "Neighbour", "Observation", "Scan",
           "SharedState", "Strategy", "StrategyChoice", "StrategyContext", "StrategyDetails",
           "make_strategy", "strategy_choice", "strategy_class"]
