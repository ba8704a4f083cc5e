"""The benchmark scripts' results files: one current row per setting, each with the commit and
command it came from, and nothing written when a test runs a harness."""

from __future__ import annotations

import json

from coverage_ros.bench import results
from coverage_ros.docgen.results import value_text


def test_a_row_replaces_the_same_settings_row_and_keeps_the_others(tmp_path, monkeypatch):
    monkeypatch.setattr(results, "RESULTS_DIR", tmp_path)
    monkeypatch.delenv("PYTEST_CURRENT_TEST")
    results.update_rows("t", [{"robots": 16, "rtf": 0.9}, {"robots": 32, "rtf": 0.8}],
                        ("robots",), ["--robots", "16"], "scripts/bench_t",
                        extra={"settings": "a"})
    results.update_rows("t", [{"robots": 16, "rtf": 1.0}], ("robots",), ["--robots", "16"],
                        "scripts/bench_t")
    data = json.loads((tmp_path / "t.json").read_text())
    assert [(r["robots"], r["rtf"]) for r in data["rows"]] == [(32, 0.8), (16, 1.0)]
    assert data["settings"] == "a"
    assert data["command"] == "scripts/bench_t --robots 16"
    assert data["rows"][-1]["run"]["command"] == "scripts/bench_t --robots 16"
    assert {"machine", "cores", "python", "date", "commit"} <= set(data)


def test_a_harness_run_by_a_test_writes_no_results_file(tmp_path, monkeypatch):
    monkeypatch.setattr(results, "RESULTS_DIR", tmp_path)
    results.write_results("t", {"x": 1}, [])
    results.update_rows("u", [{"x": 1}], ("x",), [])
    assert list(tmp_path.iterdir()) == []


def test_a_table_shows_a_run_of_consecutive_seeds_as_its_ends():
    assert value_text(list(range(5000, 5300))) == "5000 to 5299 (300)"
    assert value_text([1, 2, 3]) == "1, 2, 3"
    assert value_text([1000, 1001, 1003, 1004]) == "1000, 1001, 1003, 1004"
    assert value_text([0.5, 1.5]) == "0.5, 1.5"
