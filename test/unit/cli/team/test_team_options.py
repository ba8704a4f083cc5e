"""The launcher's options: impossible runs and faults refused before anything starts, with one
line (coverage_ros/cli/team/options.py)."""

from __future__ import annotations

import subprocess

import pytest
from conftest import entry_point
from rosutil import domain_id, ros_env

from coverage_ros.errors import ConfigError


def team_cmd(*args: str) -> list[str]:
    """coverage-team with ``args``."""
    return [entry_point("coverage-team"), *args]


@pytest.fixture(autouse=True)
def own_lock_dir(tmp_path, monkeypatch):
    """Locks of this test's runs only (the machine's real runs keep theirs)."""
    monkeypatch.setenv("COVERAGE_ROS_LOCK_DIR", str(tmp_path / "locks"))


#: Runs refused while the command line is read and the run planned (before :func:`run`).
REFUSED_WHEN_PLANNED = [
    (["--robots", "500", "--robots-per-process", "1", "--world", "l_shape"],
     "--robots: 500 robots"),
    # Robots on other hosts while discovery stays on this one (LOCALHOST): never found.
    (["--robots", "3", "--remote-robots", "2"], "--remote-robots: robots on other hosts need "
     "DDS discovery beyond this host"),
    (["--robots", "3", "--remote-robots", "3"], "--remote-robots: robot id out of range 0..2"),
    (["--robots", "3", "--remote-robots", "1", "--discovery-server", "127.0.0.1",
      "--restart", "1@5"], "--kill/--restart: cannot reach a robot on another host"),
    (["--discovery-server", "localhost:x"], "--discovery-server: must be IPV4[:PORT]"),
    (["--robot-param", "nosuch:=3"], "--robot-param nosuch: is not a robot_node parameter"),
    (["--robot-param", "control_rate:=abc"], "--robot-param control_rate: has the wrong type"),
    (["--robot-param", "strategy_params:={nosuch: 1}"],
     "--robot-param strategy_params: geodesic: unknown parameters"),
    (["--duration", "10", "--kill", "1@50"], "--kill: comes after the run's end"),
    (["--kill", "1@5", "--kill", "1@6"], "--kill: kills a robot twice"),
    (["--strategy-params", "not: [valid"], "--strategy-params: is not valid YAML ("),
    (["--until-settled", "0"], "--until-settled: must be > 0 [s]"),
    (["--explore", "--until-settled", "30"], "--until-settled: does not apply to --explore"),
]


@pytest.mark.parametrize(("args", "message"), REFUSED_WHEN_PLANNED)
def test_impossible_runs_are_refused_before_anything_starts(tmp_path, monkeypatch, capsys,
                                                            args, message):
    """The launcher's ``main`` in this process: exit status 2 and one line naming the option,
    and :func:`~coverage_ros.cli.team.launch.run` - where the domain is taken and the first
    process starts - never called."""
    from coverage_ros.cli.team import launch

    def started(plan):
        raise AssertionError(f"the run started: {plan}")

    monkeypatch.setattr(launch, "run", started)
    out = tmp_path / "team"
    assert launch.main(["--out", str(out), *args]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert not out.exists()


@pytest.mark.parametrize(("args", "message"), [
    (["--domain-id", "300"], "--domain-id: must be in 0..232"),  # (refused in run())
    (["--kill", "1@5", "--kill", "1@6"], "--kill: kills a robot twice"),
])
def test_the_command_refuses_with_status_2_and_one_line(tmp_path, args, message):
    """The installed ``coverage-team`` command, as a user runs it."""
    out = tmp_path / "team"
    proc = subprocess.run(team_cmd("--out", str(out), *args), capture_output=True, text=True,
                          timeout=120, env=ros_env(domain_id(26)))
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], proc.stderr
    assert not (out / "logs").exists()


def test_an_unknown_executor_in_the_environment_is_refused_before_anything_starts(tmp_path):
    out = tmp_path / "team"
    proc = subprocess.run(team_cmd("--out", str(out)), capture_output=True, text=True,
                          timeout=120, env=ros_env(domain_id(26), COVERAGE_ROS_EXECUTOR="bad"))
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "COVERAGE_ROS_EXECUTOR='bad'" in lines[0], proc.stderr
    assert not (out / "logs").exists()


def test_faults_are_checked_before_anything_starts():
    from coverage_ros.cli.team.faults import parse_faults as _faults

    assert [(f.time, f.robot, f.action) for f in _faults(["0@5"], ["1@3", "0@2"], 2)] == [
        (2.0, 0, "restart"), (3.0, 1, "restart"), (5.0, 0, "kill")]
    for kills, restarts, message in [([], ["2@3"], "out of range"), ([], ["1"], "ID@SECONDS"),
                                     (["1@3"], ["1@4"], "killed"), ([], ["0@-1"], ">= 0")]:
        with pytest.raises(ConfigError, match=message):
            _faults(kills, restarts, 2)


def test_an_out_that_cannot_be_the_runs_folder_and_a_viewer_without_a_display_are_refused(
        tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    env = {k: v for k, v in ros_env(domain_id(26)).items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    for args, message in (
            (["--out", str(a_file)], "--out: is a file, not a folder"),
            (["--out", str(a_file / "run")], "is a file, not a folder"),
            (["--out", str(tmp_path / "run"), "--viewer"], "--viewer: needs a display")):
        proc = subprocess.run(team_cmd(*args), capture_output=True, text=True, timeout=120,
                              env=env)
        assert proc.returncode == 2, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], proc.stderr
    assert a_file.is_file() and not (tmp_path / "run").exists()


def test_robot_params_take_their_parameters_types():
    from coverage_ros.cli.team.robots import robot_params

    got = robot_params(["control_rate:=5", "strategy_params:={escape: false}",
                        "strategy:=lloyd"])
    assert got == {"control_rate": 5.0, "strategy_params": "{escape: false}",
                   "strategy": "lloyd"}
    assert isinstance(got["control_rate"], float)
