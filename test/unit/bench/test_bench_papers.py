"""scripts/bench_papers: verdicts, rows over seeds, the table and its command line."""

from __future__ import annotations

import json
import math

import pytest

from coverage_ros.bench.papers import Experiment, Metric, experiments
from coverage_ros.bench.papers.run import main as bench_main
from coverage_ros.bench.papers.table import markdown, rows_of, verdict, worst_of
from coverage_ros.errors import ConfigError


@pytest.mark.parametrize(("better", "ours", "expected"), [
    ("lower", 0.04, "as good or better"), ("lower", 0.05, "as good or better"),
    ("lower", 0.059, "within 20 %"), ("lower", 0.061, "worse"),
    ("higher", 0.96, "as good or better"), ("higher", 0.81, "within 20 %"),
    ("higher", 0.79, "worse"),
    ("close", 1.04, "as good or better"), ("close", 0.96, "as good or better"),
    ("close", 0.85, "within 20 %"), ("close", 1.25, "worse"),
    ("lower", math.nan, "worse"),
])
def test_verdict_against_the_papers_value(better, ours, expected):
    ref = 0.05 if better == "lower" else (0.96 if better == "higher" else 1.0)
    if better == "higher" and ours == 0.81:
        ours = 0.96 * 0.85  # 15 % short
    if better == "higher" and ours == 0.79:
        ours = 0.96 * 0.75
    assert verdict(Metric("m", ref, better), ours) == expected


def test_worst_of_each_direction_skips_failed_runs():
    values = [0.1, math.nan, 0.3, 0.2]
    assert worst_of(Metric("m", 0.2, "lower"), values) == 0.3
    assert worst_of(Metric("m", 0.2, "higher"), values) == 0.1
    assert worst_of(Metric("m", 0.19, "close"), values) == 0.3
    assert math.isnan(worst_of(Metric("m", 0.2), [math.nan]))


def _experiment(**kw) -> Experiment:
    base = dict(paper="P", figure="Fig. 1", setting="s",
                metrics=(Metric("a", 0.05), Metric("b", 30.0, "higher", unit="s")),
                run=lambda seed: {"a": 0.01 * seed, "b": 30.0})
    base.update(kw)
    return Experiment(**base)


def test_rows_median_worst_and_failed_runs():
    exp = _experiment(redrawn=True, note="smaller arena")
    runs = [{"a": 0.01, "b": 31.0}, {"a": 0.04, "b": 29.0}, {"a": 0.07, "b": 33.0}]
    a, b = rows_of(exp, runs)
    assert (a.ours_median, a.ours_worst, a.seeds) == (0.04, 0.07, 3)
    assert a.verdict == "as good or better" and a.values == (0.01, 0.04, 0.07)
    assert b.ours_median == 31.0 and b.ours_worst == 29.0 and b.verdict == "as good or better"
    assert a.setting == "s (re-drawn)" and a.note == "smaller arena"
    failed = rows_of(exp, [runs[0], None, runs[2]])[0]
    assert failed.verdict == "worse" and failed.ours_median == pytest.approx(0.04)
    assert "1 of 3 runs failed" in failed.note
    row = failed.as_json()
    assert row["values"] == [0.01, None, 0.07]
    for key in ("paper", "figure", "metric", "paper_value", "ours_median", "ours_worst",
                "seeds", "verdict"):
        assert key in row
    text = markdown([a, b])
    assert text.count("\n") == 3 and "| P | Fig. 1 | s (re-drawn) | a (lower is better) |" in text
    assert "30.0 s" in text or "30 s" in text
    piped = rows_of(_experiment(metrics=(Metric("|x| / |y|", 1.0, "close"),), run=None),
                    [{"|x| / |y|": 1.0}])
    assert "| \\|x\\| / \\|y\\| (to match) |" in markdown(piped)


def test_undefined_values_and_baselines():
    exp = _experiment(metrics=(Metric("a", 0.05), Metric("t", 15.0, unit="s", baseline=True)))
    a, t = rows_of(exp, [{"a": 0.01, "t": math.nan}, {"a": 0.02, "t": 14.0},
                         {"a": 0.03, "t": 16.0}])
    assert t.ours_median == 15.0 and t.seeds == 3 and "undefined in 1 of 3 runs" in t.note
    assert t.verdict == "baseline: as good or better" and t.as_json()["baseline"] is True
    assert a.verdict == "as good or better" and a.note == ""
    nothing = rows_of(exp, [{"a": 0.01, "t": math.nan}])[1]
    assert nothing.verdict == "baseline: worse"  # no value at all: no verdict to give


def test_experiments_are_checked():
    with pytest.raises(ConfigError, match="metric names must be unique"):
        _experiment(metrics=(Metric("a", 1.0), Metric("a", 2.0)))
    with pytest.raises(ConfigError, match="seeds"):
        _experiment(seeds=0)
    with pytest.raises(ConfigError, match="better"):
        Metric("a", 1.0, "smaller")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="unknown paper"):
        experiments(["nobody"])


def test_every_registered_experiment_is_well_formed():
    exps = experiments()
    assert len({e.key for e in exps}) == len(exps)
    assert all(e.seeds >= 5 for e in exps), [e.key for e in exps if e.seeds < 5]
    assert {e.paper.split()[0] for e in exps} >= {"Lee"}


def test_command_line_lists_and_refuses(capsys):
    assert bench_main(["--paper", "lee", "--list"]) == 0
    assert "Fig. 3" in capsys.readouterr().out
    assert bench_main(["--only", "no such figure"]) == 2
    assert "select no experiment" in capsys.readouterr().err
    assert bench_main(["--seeds", "0"]) == 2


def test_command_line_runs_one_experiment_to_a_json_line(capsys, tmp_path):
    md = tmp_path / "table.md"
    assert bench_main(["--paper", "lee", "--only", "fig3", "--seeds", "1", "--jobs", "1",
                       "--markdown", str(md)]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    payload = json.loads(out[-1])
    assert payload["rows"] and all(r["seeds"] == 1 for r in payload["rows"])
    assert md.read_text().startswith("| paper |")
