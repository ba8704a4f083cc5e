"""A short soak (``coverage_ros/bench/soak.py``; the 30-minute one is ``scripts/bench_faults
--only soak``): a team at twice real time whose robots' processes are killed and started again
along the way, with the memory of every process sampled from outside."""

from __future__ import annotations

import json
import re

import pytest
from rosutil import domain_id

from coverage_ros.bench.soak import growth, soak_section

pytestmark = pytest.mark.slow


def test_growth_is_measured_after_warm_up_and_ignores_short_lives():
    flat_after_warmup = [(t, 100.0 + (50.0 if t < 10 else 0.0) * (t / 10)) for t in range(40)]
    assert growth(flat_after_warmup) == pytest.approx(0.0)
    leaking = [(t, 100.0 + t) for t in range(40)]
    assert growth(leaking) == pytest.approx(137.5 / 111.5 - 1.0)
    assert growth(leaking[:10]) is None
    # A start-up longer than the warm-up share (a robot on a slow host: imports for 13 of its
    # 30 s) is no leak; a steady leak from the start still shows.
    slow_start = [11.7, 40.1, 54.6, 74.7, 77.9, 88.5, 100.3, 106.0, 118.1, 123.7, 124.7, 125.2,
                  132.0, 150.6, 149.2, 151.0, 159.7, 149.7, 149.5, 151.9, 150.0, 149.5, 149.6,
                  150.2, 149.7, 149.7, 149.7, 157.9, 150.4, 153.8]
    assert growth(list(enumerate(slow_start))) < 0.05
    assert growth([(t, 10.0 + 5.0 * t) for t in range(30)]) > 0.5


def test_a_team_whose_robots_restart_keeps_covering_with_flat_memory_and_logs(tmp_path):
    # At twice real time, which two busy cores keep while a restarted robot's process starts:
    # the soak is about restarts, memory and logs, not speed. Without the closet escape: a
    # robot relocating across the office for half a minute raises H in the 30 s after a
    # restart that the recovery check compares with the H before it.
    r = soak_section(100.0, tmp_path, print, robots=4, world="office", period=35.0, rtf=2.0,
                     sample_period=1.0, domain=domain_id(26), strategy_params="{escape: false}")
    print(r)
    assert r["restarts"] == ["0@35", "1@70"]
    assert r["collisions"] == 0, r["collisions_by_robot"]
    assert r["H_final"] <= 0.6 * r["H_start"]
    assert all(x["recovered"] for x in r["recovered"]), r["recovered"]
    # Short lives: the restarted robots' and everyone's memory may still settle; a leak of a
    # megabyte per second (the size of a map copy every few seconds) would show as > 30 %.
    assert r["rss_growth"] is not None and r["rss_growth"] < 0.3, r["rss_growth_per_process"]
    assert {k.split("[")[0] for k in r["rss_growth_per_process"]} >= {"robot_2", "robot_3"}
    # Logs: no steady stream of lines (start-up writes most; the second half adds little).
    assert r["log_bytes_second_half"] <= max(r["log_bytes_first_half"], 20_000), r
    # Each restarted robot rejoined in real time: nobody counts it lost, and its second process
    # (one log for both) covered to the end and said so (the first was killed before it could).
    # How many updates robot 1's second life makes in its last 30 s of sim time (15 s of wall
    # time) depends on how long the process takes to start: 9 on a slow 2-core host.
    summary = json.loads((tmp_path / "soak" / "summary.json").read_text())
    robots = {x["id"]: x for x in summary["robots"]}
    assert all("lost_at" not in x for x in robots.values()), robots
    for rid, at in ((0, 35.0), (1, 70.0)):
        # (at real time the launcher looks at the clock between its scorings, which a loaded
        # machine stretches to a second or more: 2 s of sim time at --rtf 2)
        (restarted,) = robots[rid]["restarted_at"]
        assert at <= restarted <= at + 5.0, robots[rid]
        log = (tmp_path / "soak" / "logs" / f"robot_{rid}.log").read_text()
        assert log.count(f"robot {rid}: strategy geodesic") == 2, log[-2000:]
        updates = [int(n) for n in re.findall(r"(\d+) coverage updates", log)]
        assert len(updates) == 1 and updates[0] >= 1, updates
