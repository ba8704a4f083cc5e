"""A team description: which robots there are, where each starts and what each is.

A team YAML::

    robots:
      - {id: 0, start: [1.0, 1.0, 0.0]}                        # the world's robot otherwise
      - {id: 1, start: [2.0, 1.0, 0.0], radius: 0.15, v_max: 0.26, sensor_radius: 2.0}
      - {id: 2, power_weight: 0.3, lidar: {range_max: 8.0}}     # no start: placed by the sim
      - {id: 3, power_weight: sensor, role: human}              # R = its sensor radius; teleop

``role`` is ``auto`` (the default: the robot drives itself) or ``human`` (a person drives it
through its teleop topic; it keeps publishing its coverage state so that the others' cells
adapt around it). ``power_weight: sensor`` makes the power weight the robot's sensor radius
(Bhattacharya et al., Fig. 19).

Every key but ``id`` is optional: a robot's spec starts from the world's (its ``robots`` entry
of that index, else the world's ``robot`` defaults) and the keys given replace its fields.
``coverage-team`` writes the team it runs as ``<out>/team.yaml`` - every field resolved - and
hands that file to the world node, so the simulated bodies and the robot nodes (which get the
same values as parameters) agree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from coverage_ros.core.world.loading import parse_robot_entry
from coverage_ros.core.world.placement import validate_starts
from coverage_ros.core.world.robot import RobotSpec
from coverage_ros.core.world.spec import WorldSpec
from coverage_ros.core.world.yaml_io import read_yaml_mapping
from coverage_ros.errors import WorldError

TEAM_KEYS = {"robots"}
MEMBER_KEYS = {"id", "start", "role"}
#: How a robot moves: by itself or driven by a person (teleop).
ROLES = ("auto", "human")


@dataclass(frozen=True)
class TeamMember:
    """One robot of a team."""

    id: int
    start: tuple[float, float, float] | None  # (x [m], y [m], yaw [rad]); None: placed freely
    spec: RobotSpec
    role: str = "auto"  # one of ROLES


def parse_team(data: Any, world: WorldSpec, where: str = "team") -> tuple[TeamMember, ...]:
    """Validate a parsed team mapping against ``world`` (start poses free and apart)."""
    if not isinstance(data, dict):
        raise WorldError.at(where, "must be a mapping with a 'robots' list", data)
    unknown = sorted(set(data) - TEAM_KEYS)
    if unknown:
        raise WorldError.at(f"{where}: {unknown[0]}", "unknown key", expected="robots")
    entries = data.get("robots")
    if not isinstance(entries, list) or not entries:
        raise WorldError.at(f"{where}: robots", "must be a non-empty list of robots", entries)
    members: list[TeamMember] = []
    seen: set[int] = set()
    for k, entry in enumerate(entries):
        wk = f"{where}: robots[{k}]"
        if not isinstance(entry, dict) or "id" not in entry:
            raise WorldError.at(wk, "must be a mapping with an 'id'", entry)
        rid = entry["id"]
        if isinstance(rid, bool) or not isinstance(rid, int) or rid < 0:
            raise WorldError.at(f"{wk}.id", "must be an integer >= 0", rid)
        if rid in seen:
            raise WorldError.at(f"{wk}.id", "is used twice", rid)
        seen.add(rid)
        start = None
        if entry.get("start") is not None:
            start = _pose(f"{wk}.start", entry["start"])
        role = entry.get("role", "auto")
        if role not in ROLES:
            raise WorldError.at(f"{wk}.role", "unknown role", role, f"one of {list(ROLES)}")
        rest = {key: v for key, v in entry.items() if key not in MEMBER_KEYS}
        spec = parse_robot_entry(wk, rest, world.robot_spec(rid)) if rest else \
            world.robot_spec(rid)
        members.append(TeamMember(rid, start, spec, role))
    placed = [(m.start, m.spec.radius) for m in members if m.start is not None]
    validate_starts(world, [s for s, _ in placed], [r for _, r in placed],
                    f"{where}: robots (starts)")
    return tuple(members)


def _pose(where: str, value: Any) -> tuple[float, float, float]:
    if not isinstance(value, list | tuple) or len(value) not in (2, 3):
        raise WorldError.at(where, "must be [x, y] or [x, y, yaw]", value)
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise WorldError.at(where, "must be finite numbers", value)
        out.append(float(v))
    return (out[0], out[1], out[2] if len(out) == 3 else 0.0)


def load_team(path: str | Path, world: WorldSpec) -> tuple[TeamMember, ...]:
    """Read and validate a team YAML file (errors name the file)."""
    return parse_team(read_yaml_mapping(Path(path)), world, str(path))


def team_to_data(members: tuple[TeamMember, ...] | list[TeamMember]) -> dict[str, Any]:
    """The team as a YAML-ready mapping, every number field of every spec written out."""
    robots = []
    for m in members:
        entry: dict[str, Any] = {"id": m.id}
        if m.start is not None:
            entry["start"] = [round(float(v), 6) for v in m.start]
        entry["role"] = m.role
        entry.update(m.spec.numbers())
        lidar = m.spec.lidar
        entry["lidar"] = {"beams": lidar.beams, "range_min": lidar.range_min,
                          "range_max": lidar.range_max, "rate_hz": lidar.rate_hz,
                          "noise_std": lidar.noise_std, "fov": lidar.fov}
        robots.append(entry)
    return {"robots": robots}


def write_team(path: str | Path, members: tuple[TeamMember, ...] | list[TeamMember]) -> None:
    Path(path).write_text(yaml.safe_dump(team_to_data(members), sort_keys=False))
