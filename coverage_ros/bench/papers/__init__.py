"""The four papers' own experiments, reproduced side by side with their published values
(``scripts/bench_papers``).

Each paper has a module here (:mod:`.lee2024`, :mod:`.wang2024`, :mod:`.breitenmoser2010`,
:mod:`.bhattacharya2014`) whose ``experiments()`` returns :class:`Experiment` values: one
setting of the paper (a figure or a table), the values the paper reports for it
(:class:`Metric`), and a function that runs the setting once for a seed and returns our value of
every metric. :mod:`.table` runs every experiment over its seeds and reduces each metric to a
:class:`Row` - the paper's value, our median and worst value over the seeds, and a verdict.

The seed chooses the start (a start cluster drawn where the paper's agents start, or the
paper's random trials); a setting that the paper shows only as a picture is re-drawn as
faithfully as its text allows and says so (``redrawn``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Literal

from coverage_ros.errors import ConfigError

#: Which way a metric is better: ``lower`` (a cost, a time), ``higher`` (a rate, a count) or
#: ``close`` (a value to be matched, e.g. a ratio of costs that the paper reports as ~1).
Better = Literal["lower", "higher", "close"]
#: Relative margin of the "within 20 %" verdict.
NEAR_SHARE = 0.2
#: Verdicts, best first.
VERDICTS = ("as good or better", "within 20 %", "worse")


@dataclass(frozen=True)
class Metric:
    """One value the paper reports for a setting."""

    name: str  # e.g. "I, alpha-CVT"
    paper_value: float
    better: Better = "lower"
    unit: str = ""  # e.g. "s", "%", "" for a pure number
    #: A method the paper compares against, not the paper's own: its verdict says how our
    #: implementation of it compares with the paper's figure for it, not how good it is.
    baseline: bool = False

    def __post_init__(self) -> None:
        if not math.isfinite(self.paper_value):
            raise ConfigError.at(f"metric {self.name!r}: paper_value", "must be finite",
                                 self.paper_value)
        if self.better not in ("lower", "higher", "close"):
            raise ConfigError.at(f"metric {self.name!r}: better",
                                 "must be 'lower', 'higher' or 'close'", self.better)


#: One run of a setting: seed -> our value of every metric, by metric name (NaN where a value
#: is undefined for that run, e.g. an average time over no successful trial).
RunFn = Callable[[int], Mapping[str, float]]


@dataclass(frozen=True)
class Experiment:
    """A setting of a paper, the values it reports and how to run it once."""

    paper: str  # e.g. "Lee & Lee 2024"
    figure: str  # e.g. "Fig. 3", "Table I"
    setting: str  # one line: what runs (world, agents, start, method)
    metrics: tuple[Metric, ...]
    run: RunFn
    seeds: int = 5  # start clusters (or trials) to run (at least 5)
    redrawn: bool = False  # the paper shows the setting only as a picture
    slow: bool = False  # minutes per seed: left out of ``--quick``
    live: bool = False  # starts the live team (processes over DDS): never run in parallel
    note: str = ""  # how our setting differs from the paper's, if it does
    key: str = field(default="")  # unique id, e.g. "lee2024/fig3"; default paper + figure

    def __post_init__(self) -> None:
        if not self.metrics:
            raise ConfigError.at(f"{self.paper} {self.figure}: metrics", "must not be empty")
        names = [m.name for m in self.metrics]
        if len(set(names)) != len(names):
            raise ConfigError.at(f"{self.paper} {self.figure}: metrics",
                                 "metric names must be unique", names)
        if not (isinstance(self.seeds, int) and self.seeds >= 1):
            raise ConfigError.at(f"{self.paper} {self.figure}: seeds", "must be an integer >= 1",
                                 self.seeds)
        if not self.key:
            object.__setattr__(self, "key", f"{self.paper} {self.figure}")


@dataclass(frozen=True)
class Row:
    """One metric of one experiment over its seeds (a line of the table)."""

    paper: str
    figure: str
    setting: str
    metric: str
    paper_value: float
    ours_median: float
    ours_worst: float
    seeds: int
    verdict: str
    better: Better
    unit: str = ""
    redrawn: bool = False
    note: str = ""
    values: tuple[float, ...] = ()  # our value for each seed, in seed order
    baseline: bool = False  # a method the paper compares against (Metric.baseline)

    def as_json(self) -> dict:
        return {"paper": self.paper, "figure": self.figure, "setting": self.setting,
                "metric": self.metric, "paper_value": self.paper_value,
                "ours_median": _finite_or_none(self.ours_median),
                "ours_worst": _finite_or_none(self.ours_worst), "seeds": self.seeds,
                "verdict": self.verdict, "better": self.better, "unit": self.unit,
                "redrawn": self.redrawn, "note": self.note, "baseline": self.baseline,
                "values": [_finite_or_none(v) for v in self.values]}


def _finite_or_none(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


#: Paper modules, in the order of the table (short name -> module under this package).
PAPERS = {
    "lee": "lee2024",
    "wang": "wang2024",
    "breitenmoser": "breitenmoser2010",
    "bhattacharya": "bhattacharya2014",
}


def experiments(papers: list[str] | None = None) -> list[Experiment]:
    """Every registered experiment of ``papers`` (short names of :data:`PAPERS`; all by
    default), in table order. Keys are checked to be unique."""
    return [e for _, e in experiments_by_paper(papers)]


def experiments_by_paper(papers: list[str] | None = None) -> list[tuple[str, Experiment]]:
    """``(short paper name, experiment)`` pairs of :func:`experiments`."""
    import importlib

    chosen = list(PAPERS) if papers is None else papers
    out: list[tuple[str, Experiment]] = []
    for name in chosen:
        if name not in PAPERS:
            raise ConfigError.at("--paper", "unknown paper", name, ", ".join(PAPERS))
        module = importlib.import_module(f"{__name__}.{PAPERS[name]}")
        out.extend((name, e) for e in module.experiments())
    keys = [e.key for _, e in out]
    dupes = sorted({k for k in keys if keys.count(k) > 1})
    if dupes:
        raise ConfigError.at("experiments", "keys must be unique", dupes)
    return out
