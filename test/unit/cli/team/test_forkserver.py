"""The launcher's fork server (cli/team/forkserver.py, nodes/preloaded.py): a robot process
forked from it is the launcher's child in a session of its own, with its environment, log and
exit code as if the launcher had started ``ros2 run``'s executable itself.

The launcher's side runs in a process of its own here: it becomes a child subreaper, which a
pytest worker should not."""

from __future__ import annotations

import json
import subprocess
import sys

from conftest import REPO
from rosutil import domain_id, ros_env

LAUNCHER = r"""
import json, os, sys, time
from pathlib import Path
from coverage_ros.cli.team.forkserver import ForkedProcess
from coverage_ros.cli.team.processes import ProcessSet, executable, ros_args

logs = Path(sys.argv[1])
out = {}
for served in (True, False):
    folder = logs / ("served" if served else "exec")
    folder.mkdir()
    procs = ProcessSet(dict(os.environ, COVERAGE_ROS_EXECUTOR="events"), folder,
                       fork_server=served)
    # refused at start-up: one line, exit code 2
    bad = procs.start("robot_5", executable("robot_node") + ros_args(
        robot_id=5, strategy="magic"))
    code = bad.popen.wait(timeout=120)
    # one that waits for its map (there is no world): alive until stopped
    # (its own environment: the executor it names is the one it runs)
    robot = procs.start("robot_0", executable("robot_node") + ros_args(
        "/robot_0", robot_id=0, use_sim_time=True),
        extra_env={"COVERAGE_ROS_EXECUTOR": "single"})
    pid = robot.popen.pid
    deadline = time.monotonic() + 120
    while "executor:" not in robot.log.read_text() and time.monotonic() < deadline:
        time.sleep(0.1)
    out["served" if served else "exec"] = {
        "forked": isinstance(robot.popen, ForkedProcess), "refused_code": code,
        "refused_log": bad.log.read_text().strip().splitlines(),
        "parent_is_launcher": Path(f"/proc/{pid}/stat").read_text().split()[3] == str(os.getpid()),
        "own_session": os.getsid(pid) == pid,
        "name": Path(f"/proc/{pid}/comm").read_text().strip(),
        "env": "executor: single" in robot.log.read_text(),
        "started": "robot 0: strategy" in robot.log.read_text(), "alive": robot.alive}
    server = procs.server
    procs.close()
    log = folder / "forkserver.log"
    out["served" if served else "exec"].update(
        stopped_code=robot.popen.returncode, pid=pid,
        server_closed=server is None or server.popen.poll() is not None,
        server_log=log.read_text() if log.exists() else None)
print(json.dumps(out))
"""


def test_a_forked_robot_process_is_what_the_launcher_would_have_started(tmp_path):
    env = ros_env(domain_id(12))
    proc = subprocess.run([sys.executable, "-c", LAUNCHER, str(tmp_path)], env=env, cwd=REPO,
                          capture_output=True, text=True, timeout=400)
    assert proc.returncode == 0, proc.stderr[-3000:]
    runs = json.loads(proc.stdout.strip().splitlines()[-1])
    served, started = runs["served"], runs["exec"]
    assert served["forked"] and not started["forked"]
    assert served["name"] == "robot_0"  # (what top shows; a new interpreter's is "python")
    for run in (served, started):
        assert run["parent_is_launcher"] and run["own_session"] and run["env"], run
        assert run["started"] and run["alive"], run
        assert run["refused_code"] == 2 and len(run["refused_log"]) == 1, run
        assert "strategy: unknown strategy" in run["refused_log"][0]
        assert run["stopped_code"] == 0 and run["server_closed"], run
    assert served["refused_log"] == started["refused_log"]
    assert f"robot_0 is process {served['pid']}" in served["server_log"]
    assert "robot_5 is process" in served["server_log"] and started["server_log"] is None
