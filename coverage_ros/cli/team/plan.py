"""What a ``coverage-team`` run will start, decided before anything starts (pure: nothing is
started or written here): the world and the team, their parameters, the processes with their
commands and parameter files, and the environment every process gets. An impossible request is
refused here, with the option to change."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from coverage_ros.cli.team.faults import Fault, parse_faults
from coverage_ros.cli.team.lockstep import OBSERVER
from coverage_ros.cli.team.members import build_team
from coverage_ros.cli.team.network import check_reach, discovery_advice, parse_remote_robots
from coverage_ros.cli.team.options import RunConfig
from coverage_ros.cli.team.processes import executable, ros_args
from coverage_ros.cli.team.robots import (
    CONTAINER_SEARCH_REUSE,
    RobotProcess,
    default_robots_per_process,
    plan_processes,
    spec_parameters,
    team_rates,
)
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.world import TeamMember, load_planar_world
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.errors import ConfigError
from coverage_ros.nodes.runner import EXECUTOR_ENV
from coverage_ros.worlds import resolve_world_path

#: Robots per core that bench_team ran at real time (64 on 2 cores, robots sharing processes).
REAL_TIME_ROBOTS_PER_CORE = 32
STARTUP_TIMEOUT = 90.0  # [s] wall time for the world and robots to come up (16 robots, 2 cores)
REMOTE_STARTUP_TIMEOUT = 600.0  # [s] ... when robots on other hosts are started by hand
#: Environment variables the launcher's own monitor node takes from the children's.
MONITOR_ENV = ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DISCOVERY_SERVER",
               "ROS_SUPER_CLIENT")


@dataclass(frozen=True)
class RunPlan:
    """A run, planned (module docstring). ``notes``: warnings for the user."""

    config: RunConfig
    world_path: Path
    world: WorldSpec
    team: tuple[TeamMember, ...]
    domain: CoverageDomain  # the launcher's scoring: the world's density (before any region)
    faults: tuple[Fault, ...]
    remote: frozenset[int]
    processes: tuple[RobotProcess, ...]
    out: Path
    notes: tuple[str, ...]

    @property
    def robots(self) -> int:
        return len(self.team)

    @property
    def radius(self) -> float:
        """[m] the largest robot's radius."""
        return max(m.spec.radius for m in self.team)

    @property
    def startup_timeout(self) -> float:
        """[s] wall time the team gets to come up."""
        return REMOTE_STARTUP_TIMEOUT if self.remote else STARTUP_TIMEOUT

    def environment(self, base: Mapping[str, str], domain_id: int) -> dict[str, str]:
        """Every child's environment: ``base`` with the run's DDS domain and discovery."""
        env = dict(base)
        env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        env["ROS_DOMAIN_ID"] = str(domain_id)
        env["PYTHONUNBUFFERED"] = "1"
        env[EXECUTOR_ENV] = self.config.executor
        if self.config.discovery is not None:
            env["ROS_DISCOVERY_SERVER"] = "{}:{}".format(*self.config.discovery)
            env["ROS_SUPER_CLIENT"] = "TRUE"  # robots find neighbours in the graph: see all
        return env

    def world_command(self) -> list[str]:
        c = self.config
        # A restarted robot's new process answers the tick its old one owed: the world waits
        # for it as long as for a robot starting up (killed robots are removed).
        restarts: dict[str, Any] = {"lockstep_timeout": self.startup_timeout} if c.restarts else {}
        return executable("world_node") + ros_args(
            world=str(self.world_path), team=str((self.out / "team.yaml").resolve()),
            seed=c.seed, real_time_factor=float(c.rtf), clock_rate_hz=float(c.clock_rate),
            odom_rate_hz=float(c.odom_rate), status_rate_hz=2.0, publish_map=not c.explore,
            lockstep=c.lockstep, lockstep_observers=OBSERVER,
            lockstep_start_timeout=self.startup_timeout + 30.0, **restarts)

    def bridge_params(self) -> dict[str, Any]:
        """rerun_bridge's parameters (the viewer's ports are added when it starts)."""
        params: dict[str, Any] = {"robot_radius": self.radius, "world": str(self.world_path),
                                     "use_sim_time": True, "explore": self.config.explore}
        if self.config.record:
            params["record_path"] = str((self.out / "recording.rrd").resolve())
        return params


def robot_parameters(config: RunConfig, world_path: Path, team: tuple[TeamMember, ...],
                     update_load: float, state_rate: float,
                     per_process: int = 1) -> dict[int, dict[str, object]]:
    """robot_node's parameters of each robot of the team (``per_process`` to a process)."""
    shared = {"search_reuse": CONTAINER_SEARCH_REUSE} if per_process > 1 else {}
    return {m.id: {"robot_id": m.id, "use_sim_time": True, "strategy": config.strategy,
                   "world": str(world_path), "control_rate": float(config.control_rate),
                   "update_load": float(update_load), "state_rate": float(state_rate),
                   "explore": config.explore, "strategy_params": config.strategy_params,
                   "manual": m.role == "human", "map_free": config.map_free,
                   "team_size": len(team), "lockstep": config.lockstep,
                   "region": "|".join(config.regions),
                   **spec_parameters(m.spec), **shared, **config.robot_params} for m in team}


def plan_run(config: RunConfig, out: Path, env: Mapping[str, str] | None = None,
             cores: int | None = None) -> RunPlan:
    """The run of ``config`` with its output in ``out``; ``env``: the launcher's environment
    (default ``os.environ``), ``cores``: the machine's (default all)."""
    env = os.environ if env is None else env
    cores = cores or os.cpu_count() or 1
    world_path = resolve_world_path(config.world, "--world")
    world = load_planar_world(world_path, "--world")
    team = tuple(build_team(world, config))  # refuses teams the map or the machine cannot hold
    n = len(team)
    faults = parse_faults(config.kills, config.restarts, n, config.duration)
    remote = parse_remote_robots(config.remote_robots, n)
    if any(f.robot in remote for f in faults):
        raise ConfigError.at("--kill/--restart", "cannot reach a robot on another host",
                             sorted({f.robot for f in faults if f.robot in remote}))
    check_reach(dict(env), remote, config.discovery is not None)
    per_process = config.robots_per_process or default_robots_per_process(n, cores)
    load, state_rate = team_rates(n, per_process, config.update_load, config.state_rate)
    radius = max(m.spec.radius for m in team)
    domain = world_domain(world, radius)
    config.region.restrict(domain.density, world.grid, domain.free, "--region")  # refused if empty
    params = robot_parameters(config, world_path, team, load, state_rate, per_process)
    processes = plan_processes(params, per_process, {f.robot for f in faults} | set(remote),
                               out / "params")
    notes = []
    # Participants: the robot processes (here or on other hosts), the world, the launcher, the
    # bridge and the markers.
    participants = len(processes) + 2 + int(config.visualized) + int(config.markers)
    if (advice := discovery_advice(participants, config.discovery is not None)) is not None:
        notes.append(advice)
    if n > REAL_TIME_ROBOTS_PER_CORE * cores and config.rtf >= 1.0 and not config.lockstep:
        notes.append(f"warning: {n} robots on {cores} cores: beyond the "
                     f"{REAL_TIME_ROBOTS_PER_CORE} per core measured at real time "
                     "(scripts/bench_team); the run may fall behind and robots lag their "
                     "commands (--rtf below 1 keeps it in step)")
    return RunPlan(config, world_path, world, team, domain, tuple(faults), frozenset(remote),
                   tuple(processes), out, tuple(notes))
