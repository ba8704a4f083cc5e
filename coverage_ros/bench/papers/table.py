"""Reduce runs of the papers' experiments to table rows, and print the table.

A metric's runs over the seeds become one :class:`~coverage_ros.bench.papers.Row`: the median
and the worst of our values (the largest of a ``lower`` metric, the smallest of a ``higher``
one, the farthest from the paper's of a ``close`` one), and a verdict of the median against the
paper's value:

* ``as good or better`` - at or below (``lower``) / at or above (``higher``) the paper's value;
  for ``close``, within 5 % of it;
* ``within 20 %`` - no more than 20 % of the paper's value away from it on the wrong side;
* ``worse`` - farther, or a seed failed (a failed run counts as a missing value, shown as
  ``-`` and reported in the row's note).

A value a run reports as NaN is undefined for that run (an average time over no successful
trial): it is left out of the median and the worst and counted in the note, without making the
row worse. A baseline's verdict (a method the paper compares against) is marked "baseline:": it
tells how our implementation compares with the paper's figure for that method.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Mapping, Sequence

from coverage_ros.bench.papers import NEAR_SHARE, Experiment, Metric, Row

#: A ``close`` metric within this share of the paper's value counts as "as good or better".
CLOSE_SHARE = 0.05


def verdict(metric: Metric, ours: float) -> str:
    """The verdict of our (median) value against the paper's."""
    if not math.isfinite(ours):
        return "worse"
    ref = metric.paper_value
    margin = NEAR_SHARE * abs(ref)
    if metric.better == "lower":
        if ours <= ref:
            return "as good or better"
        return "within 20 %" if ours <= ref + margin else "worse"
    if metric.better == "higher":
        if ours >= ref:
            return "as good or better"
        return "within 20 %" if ours >= ref - margin else "worse"
    off = abs(ours - ref)
    if off <= CLOSE_SHARE * abs(ref):
        return "as good or better"
    return "within 20 %" if off <= margin else "worse"


def worst_of(metric: Metric, values: Sequence[float]) -> float:
    """The worst of our finite values (NaN if none is finite)."""
    ok = [v for v in values if math.isfinite(v)]
    if not ok:
        return math.nan
    if metric.better == "lower":
        return max(ok)
    if metric.better == "higher":
        return min(ok)
    return max(ok, key=lambda v: abs(v - metric.paper_value))


def rows_of(experiment: Experiment, runs: Sequence[Mapping[str, float] | None]) -> list[Row]:
    """One row per metric of ``experiment`` from its ``runs`` (one mapping per seed, in seed
    order; None for a seed whose run failed)."""
    rows = []
    failed = sum(r is None for r in runs)
    for metric in experiment.metrics:
        values = tuple(float(r[metric.name]) if r is not None and metric.name in r
                       else math.nan for r in runs)
        ok = [v for v in values if math.isfinite(v)]
        median = statistics.median(ok) if ok else math.nan
        missing = sum(r is None or metric.name not in r for r in runs)
        undefined = len(values) - len(ok) - missing
        notes = [experiment.note] if experiment.note else []
        if failed:
            notes.append(f"{failed} of {len(values)} runs failed")
        elif missing:
            notes.append(f"no value from {missing} of {len(values)} runs")
        if undefined:
            notes.append(f"undefined in {undefined} of {len(values)} runs")
        note = "; ".join(notes)
        verdict_ = "worse" if missing or not ok else verdict(metric, median)
        if metric.baseline:
            verdict_ = f"baseline: {verdict_}"
        rows.append(Row(paper=experiment.paper, figure=experiment.figure,
                        setting=experiment.setting + (" (re-drawn)" if experiment.redrawn
                                                      else ""),
                        metric=metric.name, paper_value=metric.paper_value,
                        ours_median=median, ours_worst=worst_of(metric, values),
                        seeds=len(values), verdict=verdict_, better=metric.better,
                        unit=metric.unit, redrawn=experiment.redrawn, note=note,
                        values=values, baseline=metric.baseline))
    return rows


def _fmt(value: float) -> str:
    if not math.isfinite(value):
        return "-"
    if value == 0:
        return "0"
    magnitude = abs(value)
    if magnitude >= 1000:
        return f"{value:,.0f}"
    if magnitude >= 100:
        return f"{value:.1f}"
    if magnitude >= 10:
        return f"{value:.1f}"
    return f"{value:.3g}"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def markdown(rows: Sequence[Row]) -> str:
    """The table as Markdown (one line per row; a ``|`` in a text is escaped)."""
    head = ("| paper | figure | setting | metric | paper's value | ours: median | ours: worst "
            "| seeds | verdict |\n|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        unit = f" {r.unit}" if r.unit else ""
        metric = r.metric + {"lower": " (lower is better)", "higher": " (higher is better)",
                             "close": " (to match)"}[r.better]
        lines.append(f"| {_cell(r.paper)} | {_cell(r.figure)} | {_cell(r.setting)} | "
                     f"{_cell(metric)} | "
                     f"{_fmt(r.paper_value)}{unit} | {_fmt(r.ours_median)}{unit} | "
                     f"{_fmt(r.ours_worst)}{unit} | {r.seeds} | {r.verdict} |")
    return "\n".join(lines)
