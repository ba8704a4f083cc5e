"""The robot processes of ``coverage-team``: their parameters and commands.

Each robot runs as ``robot_node`` in a process of its own, or - ``--robots-per-process K`` -
up to K robots share a ``robot_container`` process (README "Several robots per process"),
with their parameters in a parameters file of per-node sections, as for any composed node.
A robot that ``--kill`` or ``--restart`` targets, or one on another host, always gets a
process of its own: a fault must take down that robot only.
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass
from pathlib import Path

import yaml

from coverage_ros.cli.team.processes import executable, ros_args
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.errors import ConfigError
from coverage_ros.nodes.robot_parameters import PARAMETERS, SPEC_PARAMETERS

#: Fraction of the machine's cores the whole team may spend on coverage updates by default.
UPDATE_SHARE = 0.15
#: The same with several robots per process: one executor handles all of its robots' messages,
#: which leaves more for updates, pooled and taken in turns (nodes/update_worker.UpdatePool).
POOLED_UPDATE_SHARE = 0.5
#: [1/s] neighbours' coverage_state messages a robot alone in its process handles at most by
#: default (the launcher lowers state_rate for it: each message costs its executor a callback).
SOLO_STATES_PER_SECOND = 40.0
#: Robots per core up to which every robot gets a process of its own by default, and the robot
#: processes per core beyond that (the real-time figures of scripts/bench_team).
SOLO_PER_CORE = 8
PROCESSES_PER_CORE = 2
#: [m] robot_node search_reuse for robots sharing a process: a robot takes its cell from a
#: whole-map search another one made while the team stood within this of where it had them.
CONTAINER_SEARCH_REUSE = 0.2


def default_update_load(robots: int, per_process: int = 1) -> float:
    """Each robot's share of UPDATE_SHARE of the machine's cores for coverage updates (of
    POOLED_UPDATE_SHARE when robots share processes), at most 0.1: message handling in every
    robot process, the world and the launcher need the rest (measured with 16 robots on 2
    cores: robots' executors ~100 %, world ~17 %)."""
    share = UPDATE_SHARE if per_process <= 1 else POOLED_UPDATE_SHARE
    return min(0.1, share * (os.cpu_count() or 1) / max(robots, 1))


def default_state_rate(robots: int, per_process: int = 1) -> float:
    """robot_node's ``state_rate`` for the team: its default, unless robots that run alone would
    each handle more than SOLO_STATES_PER_SECOND neighbours' states a second - then as many as
    that allows (32 robots: 1.29 Hz). A robot_container parses each state once for all its
    robots, so its robots keep the default."""
    rate = float(PARAMETERS["state_rate"][0])
    if per_process > 1 or robots < 2:
        return rate
    return min(rate, SOLO_STATES_PER_SECOND / (robots - 1))


def team_rates(robots: int, per_process: int, update_load: float | None,
               state_rate: float | None) -> tuple[float, float]:
    """The robots' ``update_load`` and ``state_rate``: those asked for (``--update-load``,
    ``--state-rate``), checked, or the defaults for the team."""
    load = update_load if update_load is not None else default_update_load(robots, per_process)
    if not (math.isfinite(load) and 0 < load <= 1):
        raise ConfigError.at("--update-load", "must be a fraction in (0, 1]", load)
    rate = state_rate if state_rate is not None else default_state_rate(robots, per_process)
    if not (math.isfinite(rate) and rate > 0):
        raise ConfigError.at("--state-rate", "must be a number > 0 [Hz]", rate)
    return load, rate


def default_robots_per_process(robots: int, cores: int | None = None) -> int:
    """1 while the team has at most SOLO_PER_CORE robots per core, else enough robots per
    process for PROCESSES_PER_CORE robot processes per core."""
    cores = cores or os.cpu_count() or 1
    if robots <= SOLO_PER_CORE * cores:
        return 1
    return math.ceil(robots / (PROCESSES_PER_CORE * cores))


def robot_params(items: list[str]) -> dict[str, object]:
    """``--robot-param NAME:=VALUE`` items as robot_node parameter values, read as rcl reads
    ``-p`` values (YAML), except that a YAML mapping (``strategy_params:={variant:
    nearest}``) stays the string it is meant to be. Each name must be one of robot_node's
    parameters and each value of its type (an integer serves for a number), so that a robot
    does not refuse it after the team has started."""
    params: dict[str, object] = {}
    for item in items:
        if ":=" not in item:
            raise ConfigError.at("--robot-param", "must be NAME:=VALUE", item)
        k, v = item.split(":=", 1)
        k = k.strip()
        if k not in PARAMETERS:
            raise ConfigError.at(f"--robot-param {k}", "is not a robot_node parameter", k,
                                 "one that `robot_node --help` lists")
        try:
            value = yaml.safe_load(v)
        except yaml.YAMLError:
            value = v
        params[k] = _typed(k, v, value, PARAMETERS[k][0])
    return params


def _typed(name: str, text: str, value: object, default: object) -> object:
    """``value`` (``text`` as YAML) as the type of the parameter's ``default``."""
    if isinstance(default, str):
        return value if isinstance(value, str) else text
    if isinstance(default, bool):
        if isinstance(value, bool):
            return value
        expected = "true or false"
    elif isinstance(default, int):
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        expected = "an integer"
    else:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        expected = "a number"
    raise ConfigError.at(f"--robot-param {name}", "has the wrong type", text, expected)


def spec_parameters(spec: RobotSpec) -> dict[str, float]:
    """robot_node parameters that give it exactly ``spec`` (see nodes/robot_config.py)."""
    values = spec.numbers()
    return {param: values[field] for param, field in SPEC_PARAMETERS.items()}


@dataclass(frozen=True)
class RobotProcess:
    """One process of robots: its name in the launcher (and log file), command and robots;
    a ``robot_container`` reads its robots' parameters from ``params_file``, whose contents
    are ``params_text`` (written by the launcher before it starts the process)."""

    name: str
    cmd: list[str]
    ids: tuple[int, ...]
    params_file: Path | None = None
    params_text: str = ""


def robot_node_command(rid: int, params: dict[str, object]) -> list[str]:
    """``robot_node`` for robot ``rid`` with ``params`` (as ``ros2 run`` would take it)."""
    return executable("robot_node") + ros_args(f"/robot_{rid}", **params)


def group_name(ids: list[int]) -> str:
    """The process (and log) name of a group of robot ids in increasing order:
    ``robots_<first>-<last>`` for consecutive ids, ``robots_<first>-<last>_every_<step>`` for
    ids a fixed step apart, else ``robots_<id>_<id>_...``."""
    steps = {b - a for a, b in itertools.pairwise(ids)}
    if len(steps) != 1:
        return "robots_" + "_".join(str(i) for i in ids)
    step = steps.pop()
    return f"robots_{ids[0]}-{ids[-1]}" + ("" if step == 1 else f"_every_{step}")


def plan_processes(params: dict[int, dict[str, object]], per_process: int,
                   alone: set[int], params_dir: Path) -> list[RobotProcess]:
    """The processes for robots ``{id: parameters}``: groups of up to ``per_process`` ids in a
    ``robot_container`` (parameters written to ``params_dir``), and a ``robot_node`` of its
    own for each robot in ``alone`` and for a group of one. Pure: the files are in the plan.

    The ids are dealt to the groups in turn (0, G, 2G, ... in the first of G groups): the
    launcher's start cluster fills ring by ring in id order, and the robots of the outer ring,
    whose cells are largest and whose updates cost most, would otherwise all share one
    process and its one update at a time (64 robots in groups of 16 consecutive ids: the 16
    outer robots in one process, robots there waiting 8 s for their turn)."""
    out = [RobotProcess(f"robot_{rid}", robot_node_command(rid, params[rid]), (rid,))
           for rid in sorted(alone)]
    shared = [rid for rid in sorted(params) if rid not in alone]
    count = math.ceil(len(shared) / per_process)
    for g in range(count):
        ids = shared[g::count]
        if len(ids) == 1:
            out.append(RobotProcess(f"robot_{ids[0]}",
                                    robot_node_command(ids[0], params[ids[0]]), (ids[0],)))
            continue
        name = group_name(ids)
        path = (params_dir / f"{name}.yaml").resolve()
        text = yaml.safe_dump(
            {f"/robot_{rid}/coverage_robot": {"ros__parameters": params[rid]} for rid in ids},
            sort_keys=False)
        cmd = executable("robot_container") + [str(rid) for rid in ids] + \
            ["--ros-args", "--params-file", str(path)]
        out.append(RobotProcess(name, cmd, tuple(ids), path, text))
    return sorted(out, key=lambda p: p.ids[0])

