"""The launcher's child processes (cli/team/processes.py): what each child sets up between fork
and exec."""

from __future__ import annotations

import os
import subprocess
import sys
import time

from coverage_ros.cli.team.processes import _child_setup


def test_a_child_whose_launcher_died_before_it_asked_for_the_signal_ends_at_once():
    """The kernel only signals a child whose parent dies after its PR_SET_PDEATHSIG request; a
    child that finds it already has another parent ends instead of living on."""
    t0 = time.monotonic()
    proc = subprocess.Popen(["sleep", "30"], preexec_fn=_child_setup(parent=1))  # (not ours)
    assert proc.wait(timeout=10) == 0
    assert time.monotonic() - t0 < 5.0
    t0 = time.monotonic()  # (with its parent alive it runs to the end)
    proc = subprocess.Popen(["sleep", "0.5"], preexec_fn=_child_setup(parent=os.getpid()))
    assert proc.wait(timeout=10) == 0
    assert time.monotonic() - t0 >= 0.5


def test_a_child_holding_a_broken_port_open_is_killed_and_started_again(tmp_path):
    """(Without DDS: the child opens an unsized port file and sleeps, as one stuck in Fast DDS
    does; started again, it finds the file gone and ends.)"""
    from pathlib import Path

    from coverage_ros.cli.team.processes import ProcessSet

    port = tmp_path / "fastrtps_port7007"
    port.touch()
    logs = tmp_path / "logs"
    logs.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "FASTDDS_BUILTIN_TRANSPORTS"}
    procs = ProcessSet(env, logs)
    hold = f"import time; f = open({str(port)!r}, 'rb'); time.sleep(60)"
    first = procs.start("robot_3", [sys.executable, "-c", hold])
    try:
        deadline = time.monotonic() + 20.0
        while not procs.stuck_on_broken_ports() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert procs.stuck_on_broken_ports() == {"robot_3": [Path(port)]}
        said: list[str] = []
        assert procs.restart_stuck(said.append, recheck=0.1) == ["robot_3"]
        assert first.popen.poll() is not None and not port.exists()
        assert len(said) == 1 and "robot_3" in said[0] and "fastrtps_port7007" in said[0]
        again = procs.children["robot_3"]
        assert again.popen.pid != first.popen.pid and again.popen.wait(timeout=20) == 1
        # (the new process keeps off shared memory: it would take over the killed one's port)
        assert again.extra_env == {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
        assert procs.restart_stuck(said.append, recheck=0.1) == []
    finally:
        procs.stop()


def test_a_child_started_again_keeps_its_command_and_log_and_keeps_off_shared_memory(tmp_path):
    from coverage_ros.cli.team.processes import ProcessSet

    env = {k: v for k, v in os.environ.items() if k != "FASTDDS_BUILTIN_TRANSPORTS"}
    procs = ProcessSet(env, tmp_path)
    say = "import os; print(os.environ.get('FASTDDS_BUILTIN_TRANSPORTS'), os.environ['ROBOT'])"
    first = procs.start("robot_1", [sys.executable, "-c", say], extra_env={"ROBOT": "1"})
    assert first.popen.wait(timeout=20) == 0
    again = procs.start_again("robot_1")
    assert again.popen.wait(timeout=20) == 0 and again.cmd == first.cmd
    assert (tmp_path / "robot_1.log").read_text().split("\n")[:2] == ["None 1", "UDPv4 1"]
