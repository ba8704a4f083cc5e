"""What coverage-team runs, decided before any process starts: the robots (team file, world,
options) and whether the machine and the map can hold them at all."""

from __future__ import annotations

import math
from dataclasses import replace

from coverage_ros.cli.team.options import RunConfig
from coverage_ros.cli.team.robots import default_robots_per_process
from coverage_ros.core.world import TeamMember, load_team
from coverage_ros.core.world.placement import check_free_area, team_starts
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.errors import ConfigError

#: [MB] memory of one robot process, of each further robot sharing a process, the world node
#: and the rerun bridge (scripts/bench_team's peaks, rounded up): a team's estimate at start.
ROBOT_MB = 300.0
SHARED_ROBOT_MB = 20.0
WORLD_MB = 150.0
BRIDGE_MB = 300.0
MARKERS_MB = 100.0  # the RViz marker node


def build_team(world: WorldSpec, config: RunConfig) -> list[TeamMember]:
    """The robots to run, from ``--team`` (else ``--robots`` robots of the world), with the
    launcher's options applied: ``--sensor-radius``, ``--starts`` (or the team file's starts,
    else the world's or a seeded cluster) and ``--human``."""
    if config.team_file is not None:
        members = list(load_team(config.team_file, world))
        if config.robots is not None and config.robots != len(members):
            raise ConfigError.at("--robots", f"differs from the {len(members)} robots of "
                                 f"{config.team_file}", config.robots)
        ids = sorted(m.id for m in members)
        if ids != list(range(len(members))):
            raise ConfigError.at(f"{config.team_file}: robots", "ids must be 0..N-1, each once",
                                 ids, f"0..{len(members) - 1}")
        members.sort(key=lambda m: m.id)
        given = [m.start is not None for m in members]
        if any(given) and not all(given):
            raise ConfigError.at(f"{config.team_file}: robots",
                                 "give every robot a start or none",
                                 [m.id for m in members if m.start is None])
    else:
        n = 4 if config.robots is None else config.robots
        members = [TeamMember(i, None, world.robot_spec(i)) for i in range(n)]
    if config.sensor_radius is not None:
        members = [replace(m, spec=m.spec.with_overrides(
            {"sensor_radius": config.sensor_radius}, "--sensor-radius")) for m in members]
    per_process = config.robots_per_process or default_robots_per_process(len(members))
    check_room(world, len(members), max(m.spec.radius for m in members), config.visualized,
               config.markers, per_process=per_process)
    if config.starts or any(m.start is None for m in members):
        starts = team_starts(world, [m.spec for m in members], config.starts, config.seed)
        members = [replace(m, start=(float(starts[i][0]), float(starts[i][1]),
                                     float(starts[i][2])))
                   for i, m in enumerate(members)]
    for rid in config.humans:
        if not 0 <= rid < len(members):
            raise ConfigError.at("--human", f"robot id out of range 0..{len(members) - 1}", rid)
        members[rid] = replace(members[rid], role="human")
    return members


def robots_mb(robots: int, per_process: int = 1) -> float:
    """[MB] estimated memory of ``robots`` robots, ``per_process`` to a process."""
    processes = math.ceil(robots / max(per_process, 1))
    return processes * ROBOT_MB + (robots - processes) * SHARED_ROBOT_MB


def check_room(world: WorldSpec, robots: int, radius: float, bridge: bool,
               markers: bool = True, available_mb: float | None = None,
               per_process: int = 1) -> None:
    """Refuse a team that cannot work: more robots than the free area holds at their radius
    and spacing (hexagonal packing, CLUSTER_GAP apart), or more memory than the machine has
    available (``available_mb``: default, what psutil says) for them, ``per_process`` robots
    to a process."""
    check_free_area(world, robots, radius, radius_where="radius (of the world's or team "
                    "file's robots)")
    need = robots_mb(robots, per_process) + WORLD_MB + (BRIDGE_MB if bridge else 0.0) + \
        (MARKERS_MB if markers else 0.0)
    if available_mb is None:
        import psutil

        available_mb = psutil.virtual_memory().available / 2**20
    if need > available_mb:
        most = robots
        while most > 0 and robots_mb(most, per_process) + need - robots_mb(robots, per_process) \
                > available_mb:
            most -= 1
        raise ConfigError.at("--robots", f"{robots} robots need about {need / 1024:.1f} GB of "
                             f"memory ({ROBOT_MB:g} MB per robot process, {per_process} "
                             f"robot(s) per process, {SHARED_ROBOT_MB:g} MB for each further "
                             f"one); the machine has {available_mb / 1024:.1f} GB available",
                             expected=f"at most {most}, or more robots per process "
                             "(--robots-per-process)")
