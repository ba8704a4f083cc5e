"""drive: false - the robot publishes its coverage goal for its own navigator (Nav2) and no
cmd_vel: a live team driven by a stand-in navigator process (the relay's rules and the
parameter checks: unit/core/control/test_goal_relay.py, unit/nodes/test_goal_output.py)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import NO_ESCAPE, REPO, entry_point
from rosutil import NodeProcess, domain_id
from teamdiag import team_diagnosis


@pytest.mark.slow
def test_a_team_with_its_own_navigation_and_localization_converges(tmp_path):
    """Three robots set up as on a Nav2 robot: drive: false, driven by a stand-in navigator
    that only sees their goal_pose topics, and pose_source: tf (the pose from /tf, as AMCL
    gives it). No robot node publishes cmd_vel, each goal differs from the previous one by more
    than the resend distance, and the team spreads as one that drives itself does."""
    domain = domain_id(3)
    result = tmp_path / "nav.json"
    nav = NodeProcess([sys.executable, str(REPO / "test" / "nav_stub.py"), str(result),
                       "0", "1", "2"], domain)
    with nav:
        out = tmp_path / "team"
        # At twice real time: three robots and the navigator keep up on two cores. (Without
        # the closet escape: the test is of the hand-off, and a settled team's pricing of
        # moves would take the robots' update budget.)
        proc = subprocess.run(
            [entry_point("coverage-team"), "--quiet", "--world", "empty",
             "--robots", "3", "--duration", "45", "--seed", "2", "--rtf", "2", "--out", str(out),
             "--domain-id", str(domain), "--robot-param", "drive:=false",
             "--robot-param", "pose_source:=tf", *NO_ESCAPE],
            capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert nav.stop() == 0, nav.output()[-2000:]
    got = json.loads(result.read_text())
    summary = json.loads((out / "summary.json").read_text())
    m = summary["metrics"]
    assert m["H"] <= 0.5 * m["H_start"], team_diagnosis(summary, out)
    for rid in ("0", "1", "2"):
        assert got["cmd_vel_publishers"][rid] == [], got["cmd_vel_publishers"]
        goals = np.array([g[1:4] for g in got["goals"][rid]])
        assert len(goals) >= 2, got["goals"][rid]
        assert all(g[4] == "map" for g in got["goals"][rid])
        steps = np.hypot(*np.diff(goals[:, :2], axis=0).T)
        # moved by more than the resend distance, or the last goal again for a subscriber that
        # appeared on goal_pose since (the bridge, the markers or this navigator)
        assert ((steps > 0.25) | (steps == 0.0)).all() and (steps > 0.25).any(), steps
        # Its coverage_state carries the velocity its navigator drives it at (from its
        # poses): the stub drives at 0.18 m/s at most.
        assert 0.05 < got["state_speed"][rid] < 0.3, got["state_speed"]
    for r in summary["robots"]:
        assert r["path_length"] > 0.3, r
        log = (out / "logs" / f"robot_{r['id']}.log").read_text()
        assert f"pose from /tf (map -> robot_{r['id']}/base_link)" in log, log[-2000:]
