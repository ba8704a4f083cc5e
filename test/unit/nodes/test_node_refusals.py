"""Node processes refuse a bad start-up with one line naming the parameter, the file or the
value, and exit before they join any DDS traffic (each runs on its own domain all the same)."""

from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import REPO
from rosutil import domain_id, ros_env


@pytest.mark.parametrize("args, message", [
    (["-r", "__ns:=/somewhere"], "robot_id: not set and the namespace '/somewhere'"),
    (["-p", "robot_id:=0", "-p", "strategy:=magic"], "strategy: unknown strategy"),
    (["-p", "robot_id:=0", "-p", "control_rate:=0.0"], "control_rate: must be a number > 0"),
    (["-p", "robot_id:=0", "-p", "world:=nowhere"], "no shipped world of that name"),
    (["-p", "robot_id:=0", "-p", "strategy_params:=justtext"], "strategy_params: must be a YAML"),
    (["-p", "robot_id:=0", "-p", "strategy_params:=[1, 2]"], "'strategy_params'"),
    (["-p", "robot_id:=0", "-p", "map_free:=true", "-p", "world:=office"],
     "map_free: strategy geodesic needs a map"),
    (["-p", "robot_id:=0", "-p", "map_free:=true", "-p", "strategy:=bvc"],
     "map_free: needs the area: 'world' or 'bounds'"),
])
def test_bad_parameters_exit_with_one_line(args, message):
    env = ros_env(domain_id(11))
    out = subprocess.run([sys.executable, "-m", "coverage_ros.nodes.robot_node", "--ros-args",
                          *args], env=env, capture_output=True, text=True, timeout=180, cwd=REPO)
    assert out.returncode == 2
    err = out.stderr.strip().splitlines()
    assert len(err) == 1 and message in err[0], out.stderr


def test_an_unknown_executor_is_refused_with_one_line():
    env = ros_env(domain_id(11), COVERAGE_ROS_EXECUTOR="fast")
    out = subprocess.run([sys.executable, "-m", "coverage_ros.nodes.robot_node", "--ros-args",
                          "-p", "robot_id:=0"], env=env, capture_output=True, text=True,
                         timeout=180, cwd=REPO)
    assert out.returncode == 2
    err = out.stderr.strip().splitlines()
    assert len(err) == 1 and "COVERAGE_ROS_EXECUTOR='fast'" in err[0], out.stderr


BAD_WORLDS = [
    ("missing_map", "map: nowhere.yaml\n", "nowhere.yaml: file not found"),
    ("malformed", "bounds: [0, 0, 5\nname: x\n", "malformed YAML"),
    ("unknown_key", "bounds: [0, 0, 5, 5]\ncolour: red\n", "colour: unknown key"),
    ("start_in_obstacle", "bounds: [0, 0, 5, 5]\nobstacles: [{type: circle, center: [2, 2], "
     "radius: 0.5}]\nrobots: [[2, 2, 0]]\n", "inside an obstacle"),
    ("start_outside", "bounds: [0, 0, 5, 5]\nrobots: [[9, 2, 0]]\n", "outside the map"),
    ("bad_radius", "bounds: [0, 0, 5, 5]\nrobot: {radius: -0.1}\n", "radius: must be > 0"),

]


@pytest.mark.parametrize("case, world_yaml, expected", BAD_WORLDS,
                         ids=[c[0] for c in BAD_WORLDS])
def test_bad_world_gives_a_one_line_error(tmp_path, case, world_yaml, expected):
    path = tmp_path / f"{case}.yaml"
    path.write_text(world_yaml)
    out = subprocess.run(
        [sys.executable, "-m", "coverage_ros.nodes.world_node", "--ros-args", "-p",
         f"world:={path}"], cwd=REPO, env=ros_env(domain_id(1)), capture_output=True, text=True,
        timeout=120)
    assert out.returncode != 0
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith("world_node: error: ") and expected in lines[0]
    assert case in lines[0] or case == "missing_map"  # names the file


@pytest.mark.parametrize("node, parameter", [
    ("world_node", "world"), ("robot_node", "strategy"), ("rerun_bridge", "record_path"),
    ("marker_node", "robot_prefix")])
def test_help_prints_the_usage_and_every_parameter_without_starting(node, parameter):
    from coverage_ros.nodes.reference import node_tables

    env = ros_env(domain_id(11))
    out = subprocess.run([sys.executable, "-m", f"coverage_ros.nodes.{node}", "--help"], env=env,
                         capture_output=True, text=True, timeout=180, cwd=REPO)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith(f"usage: ros2 run coverage_ros {node} ")
    listed = {line.split()[0] for line in out.stdout.splitlines() if line.startswith("  ")}
    assert parameter in listed and listed == set(node_tables()[node])
    assert "executor" not in out.stderr  # (no node was built)


def test_help_after_ros_arguments_is_a_ros_argument():
    from coverage_ros.nodes.runner import wants_help

    assert wants_help(["robot_node", "--help"]) and wants_help(["robot_node", "-h", "--ros-args"])
    assert not wants_help(["robot_node", "--ros-args", "-p", "x:=1", "--help"])
