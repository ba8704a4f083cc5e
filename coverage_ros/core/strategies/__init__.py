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
import importlib
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

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
from coverage_ros.errors import ConfigError


class _Registry(Mapping[str, type[Strategy]]):
    """Strategy classes by name, each imported when first asked for: a process imports the
    strategies it runs, not every one (the world node imports none)."""

    def __init__(self, paths: dict[str, str]) -> None:
        self._paths = paths  # name -> "module:Class"
        self._loaded: dict[str, type[Strategy]] = {}

    def __getitem__(self, name: str) -> type[Strategy]:
        cls = self._loaded.get(name)
        if cls is None:
            module, attr = self._paths[name].split(":")
            cls = getattr(importlib.import_module(module), attr)
            if cls.name != name:
                raise ValueError(f"strategy {self._paths[name]} is named {cls.name!r}, "
                                 f"registered as {name!r}")
            self._loaded[name] = cls
        return cls

    def __iter__(self) -> Iterator[str]:
        return iter(self._paths)

    def __len__(self) -> int:
        return len(self._paths)

    def __contains__(self, name: object) -> bool:
        return name in self._paths


_PACKAGE = "coverage_ros.core.strategies"
STRATEGIES: Mapping[str, type[Strategy]] = _Registry({
    "acvt": f"{_PACKAGE}.acvt.strategy:AcvtStrategy",
    "bvc": f"{_PACKAGE}.bvc.strategy:BvcStrategy",
    "geodesic": f"{_PACKAGE}.geodesic:GeodesicStrategy",
    "lloyd": f"{_PACKAGE}.lloyd:LloydStrategy",
    "tangentbug": f"{_PACKAGE}.tangentbug.strategy:TangentBugStrategy",
})
#: The strategies of a team exploring an unknown map.
EXPLORERS: Mapping[str, type[Strategy]] = _Registry({
    "geodesic": f"{_PACKAGE}.explore.strategy:ExploreStrategy",
    "frontier": f"{_PACKAGE}.frontier.strategy:FrontierStrategy",
})


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
