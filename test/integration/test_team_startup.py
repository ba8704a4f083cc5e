"""Robot processes forked from the launcher's preloaded interpreter run the team exactly as new
interpreters do (scripts/bench_startup's short version: four robots on the office, one run
each way; the CPU it saves is the benchmark's to show)."""

from __future__ import annotations

import json

import pytest

from coverage_ros.bench.startup import main

pytestmark = [pytest.mark.slow, pytest.mark.lockstep]


def test_a_team_of_forked_robot_processes_ends_as_one_of_new_interpreters(capsys):
    assert main(["--repeats", "1", "--only", "0", "--no-results"]) == 0
    row, = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["rows"]
    assert row["same_summary"] and row["robots"] == 4 and row["world"] == "office", row
    assert row["forked_processes"] == [4, 0], row  # (each robot a process of its own)
