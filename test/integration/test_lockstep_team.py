"""Lock-step simulation with the real processes over DDS: one command and seed give the same
summary however busy the machine is; robots started by hand join the barrier, and a robot that
dies leaves it after the timeout instead of freezing the team."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest
from conftest import NO_ESCAPE, entry_point, shared_map
from rosutil import NodeProcess, RosClient, domain_id

from coverage_ros.bench.lockstep import cpu_hogs, differences
from coverage_ros.cli.team.summary import WALL_CLOCK_KEYS, deterministic_part, summary_table

pytestmark = [pytest.mark.slow, pytest.mark.lockstep]


def team_cmd(*args: str) -> list[str]:
    """coverage-team with ``args``."""
    return [entry_point("coverage-team"), "--quiet", "--lockstep", "--no-markers", *args]


def test_one_command_and_seed_give_the_same_summary_beside_a_cpu_hog(tmp_path):
    """Four geodesic robots, two per process (their shared search cache, their one driver
    thread), with a region of interest: run twice, the second time beside two busy
    processes; everything but the wall-clock figures is the same."""
    sandbox = shared_map("tb3_sandbox")
    args = ["--world", str(sandbox), "--robots", "4", "--duration", "30", "--seed", "3",
            "--robots-per-process", "2", "--region", "-1.8,-1.8;1.0,-1.8;1.0,1.0;-1.8,1.0"]
    summaries = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        cmd = team_cmd("--out", str(out), "--domain-id", str(domain_id(22 + k)), *args)
        with cpu_hogs(2 if k else 0):
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-3000:]
        summaries.append(json.loads((out / "summary.json").read_text()))
        assert "going on without" not in "".join(
            p.read_text() for p in (out / "logs").glob("robots_*.log"))
    first, second = summaries
    print(f"rtf {first['rtf']} alone, {second['rtf']} beside two CPU hogs")
    assert set(WALL_CLOCK_KEYS) & set(first) == {"wall_time", "rtf"}
    assert differences(deterministic_part(first), deterministic_part(second)) == []
    assert len(first["metrics"]["H_series"]) == 7  # every 5 s of sim time, and the end
    assert first["metrics"]["H"] < 0.5 * first["metrics"]["H_start"]


def test_robots_started_by_hand_join_and_a_dead_one_leaves_after_the_timeout():
    """world_node lock-step with three bodies and a short start timeout; robots 0 and 1 start
    (ros2 run style), the world begins with them; robot 2 starts later and joins from the next
    tick; robot 1 is killed (SIGKILL: no goodbye) and the world goes on without it after
    lockstep_timeout, with one warning."""
    from rosgraph_msgs.msg import Clock

    from coverage_ros.nodes import conversions as conv

    domain = domain_id(24)

    def robot(rid: int) -> NodeProcess:
        return NodeProcess([sys.executable, "-m", "coverage_ros.nodes.robot_node", "--ros-args",
                            "-r", f"__ns:=/robot_{rid}", "-p", "use_sim_time:=true",
                            "-p", "world:=l_shape", "-p", "lockstep:=true"], domain)

    def up(*nodes: NodeProcess) -> bool:
        assert all(n.alive() for n in nodes), "".join(n.output()[-2000:] for n in nodes)
        return all("executor:" in n.output() for n in nodes)

    def sim_time() -> float:
        return conv.from_time_msg(client.wait_for("/clock", Clock, timeout=30.0).clock)

    client = RosClient(domain)
    try:
        # Robots 0 and 1 are up before the world starts, so that its 8 s of waiting for them at
        # the start are spent on discovery, not on their imports on a loaded machine.
        with robot(0) as r0, robot(1) as r1:
            client.spin_until(lambda: up(r0, r1), 120.0, "robots 0 and 1 to start")
            with NodeProcess.world_node(domain, "world:=l_shape", "num_robots:=3",
                                        "lockstep:=true", "lockstep_start_timeout:=8.0",
                                        "lockstep_timeout:=3.0",
                                        "real_time_factor:=4.0") as world:
                client.spin_until(lambda: "lock-step: first tick with robots [0, 1]"
                                  in world.output(), 60.0, "the first tick")
                t0 = sim_time()
                with robot(2) as r2:
                    client.spin_until(lambda: "robot 2 joined: listed from tick"
                                      in world.output(), 60.0, "robot 2 to join")
                    assert sim_time() > t0
                    r1.signal(signal.SIGKILL)
                    killed = time.monotonic()
                    try:
                        client.spin_until(lambda: "robot 1 silent for" in world.output(), 30.0,
                                          "the world to give up on robot 1")
                    except TimeoutError:
                        print(world.output()[-3000:], r0.output()[-2000:], r2.output()[-2000:])
                        raise
                    gave_up = time.monotonic() - killed
                    t1 = sim_time()
                    client.spin_for(2.0)
                    # The team goes on (at most 4x real time), nobody waiting for a state
                    # robot 1 may have died before sending.
                    assert sim_time() > t1 + 1.0, world.output()[-3000:] + r0.output()[-3000:]
                    assert r0.alive() and r2.alive(), r0.output() + r2.output()
                said = world.output()
    finally:
        client.close()
    print(f"the world gave up on the dead robot {gave_up:.1f} s after it died")
    # [s] the 3 s of silence count from the tick robot 1 died in, sent out before the kill
    assert 2.0 <= gave_up <= 10.0
    assert said.count("robot 1 silent for") == 1


def test_a_team_run_until_settled_ends_once_h_has_stood_still(tmp_path):
    """--until-settled 20 with a 400 s --duration: three geodesic robots spread over the L
    and the run ends once H has stayed within 1 % for 20 s of sim time, long before 400 s.
    (Without the closet escape: a team with it ends settled in test_team.py.)"""
    out = tmp_path / "run"
    proc = subprocess.run(team_cmd("--out", str(out), "--domain-id", str(domain_id(25)),
                                   "--world", "l_shape", "--robots", "3", "--seed", "0",
                                   "--duration", "400", "--until-settled", "20",
                                   *NO_ESCAPE),
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    end = summary["sim_time"] - summary["ready_at"]
    assert summary["settled_at"] == pytest.approx(end, abs=1e-3)
    assert 20.0 <= end < 150.0, summary["sim_time"]
    assert f"settled at {end:.1f} s (--until-settled)" in summary_table(summary)
    series = summary["metrics"]["H_series"]
    last = [h for t, h in series if t >= end - 20.0 - 1e-6]
    assert len(last) >= 5 and max(last) <= 1.01 * min(last), series
    assert summary["metrics"]["H"] < 0.2 * summary["metrics"]["H_start"]
