"""What a robot is: its body, limits, sensing and coverage weight (:class:`RobotSpec`).

One frozen :class:`RobotSpec` per robot is built once - from the world file (its ``robot``
defaults and per-robot ``robots`` entries), a team description and the launcher's options - and
the same value reaches the simulated body (``coverage_ros.sim``), the robot's controller and
strategy (``coverage_ros.core.control``) and the team's scoring. ``robot_node`` parameters
override it field by field (:meth:`RobotSpec.with_overrides`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Any

from coverage_ros.errors import ConfigError

# TurtleBot3 Burger defaults (ROBOTIS e-Manual specifications, and nav2's tb3 DWB limits for the
# accelerations).
TB3_RADIUS = 0.105  # [m] footprint radius
TB3_V_MAX = 0.22  # [m/s] maximum linear speed
TB3_W_MAX = 2.84  # [rad/s] maximum angular speed
TB3_A_MAX = 2.5  # [m/s^2] linear acceleration limit (nav2 tb3 acc_lim_x)
TB3_ALPHA_MAX = 3.2  # [rad/s^2] angular acceleration limit (nav2 tb3 acc_lim_theta)
# LDS-01 lidar defaults.
LDS_BEAMS = 360
LDS_RANGE_MIN = 0.12  # [m]
LDS_RANGE_MAX = 3.5  # [m]
LDS_RATE_HZ = 5.0  # [Hz]
#: [m] default sensing radius (coverage ratio, sensor-based strategies): the LDS-01's range.
DEFAULT_SENSOR_RADIUS = LDS_RANGE_MAX


@dataclass(frozen=True)
class LidarSpec:
    """A planar lidar (defaults: LDS-01 on the TurtleBot3)."""

    beams: int = LDS_BEAMS
    range_min: float = LDS_RANGE_MIN  # [m]
    range_max: float = LDS_RANGE_MAX  # [m]
    rate_hz: float = LDS_RATE_HZ  # [Hz] scans per second
    noise_std: float = 0.0  # [m] Gaussian range noise
    fov: float = 2.0 * math.pi  # [rad] field of view, centred on the robot's heading

    def __post_init__(self) -> None:
        if not isinstance(self.beams, int) or isinstance(self.beams, bool) or self.beams < 1:
            raise ConfigError.at("lidar.beams", "must be an integer >= 1", self.beams)
        if not 0 <= self.range_min < self.range_max or not math.isfinite(self.range_max):
            raise ConfigError.at("lidar.range_min/range_max",
                                 "need 0 <= range_min < range_max < inf",
                                 (self.range_min, self.range_max))
        if not self.rate_hz > 0:
            raise ConfigError.at("lidar.rate_hz", "must be > 0", self.rate_hz)
        if not self.noise_std >= 0:
            raise ConfigError.at("lidar.noise_std", "must be >= 0", self.noise_std)
        if not 0 < self.fov <= 2.0 * math.pi + 1e-9:
            raise ConfigError.at("lidar.fov", "must be in (0, 2*pi]", self.fov)

    @property
    def angle_increment(self) -> float:
        """[rad] between beams (a full circle does not repeat its first beam)."""
        full = self.fov >= 2.0 * math.pi - 1e-9
        return self.fov / (self.beams if full else max(self.beams - 1, 1))

    @property
    def angle_min(self) -> float:
        return -0.5 * self.fov if self.fov < 2.0 * math.pi - 1e-9 else -math.pi


#: RobotSpec fields that are plain numbers > 0 (``power_weight`` may be 0).
POSITIVE_FIELDS = ("radius", "v_max", "w_max", "a_max", "alpha_max", "sensor_radius")
#: Number fields of a RobotSpec, in the order tables and messages show them.
NUMBER_FIELDS = (*POSITIVE_FIELDS, "power_weight")


@dataclass(frozen=True)
class RobotSpec:
    """Body, limits and sensing of one differential-drive robot (defaults: TurtleBot3 Burger
    with its LDS-01 lidar)."""

    radius: float = TB3_RADIUS  # [m] footprint radius (inflates the map)
    v_max: float = TB3_V_MAX  # [m/s]
    w_max: float = TB3_W_MAX  # [rad/s]
    a_max: float = TB3_A_MAX  # [m/s^2]
    alpha_max: float = TB3_ALPHA_MAX  # [rad/s^2]
    sensor_radius: float = DEFAULT_SENSOR_RADIUS  # [m] coverage sensing radius
    power_weight: float = 0.0  # [m] R of the power Voronoi cells: f(x) = x^2 - R^2
    lidar: LidarSpec = field(default_factory=LidarSpec)

    def __post_init__(self) -> None:
        for name in NUMBER_FIELDS:
            value = getattr(self, name)
            if (isinstance(value, bool) or not isinstance(value, int | float)
                    or not math.isfinite(value)):
                raise ConfigError.at(f"robot.{name}", "must be a finite number", value)
            if name == "power_weight" and value < 0:
                raise ConfigError.at(f"robot.{name}", "must be >= 0 [m]", value)
            if name != "power_weight" and value <= 0:
                raise ConfigError.at(f"robot.{name}", "must be > 0", value)
        if not isinstance(self.lidar, LidarSpec):
            raise ConfigError.at("robot.lidar", "must be a lidar specification", self.lidar)

    def with_overrides(self, values: dict[str, Any], where: str = "robot") -> RobotSpec:
        """This spec with some number fields replaced (``values`` maps field names to numbers;
        unknown names are refused)."""
        unknown = sorted(set(values) - set(NUMBER_FIELDS))
        if unknown:
            raise ConfigError.at(f"{where}.{unknown[0]}", "unknown robot field",
                                 expected=f"one of {list(NUMBER_FIELDS)}")
        try:
            return replace(self, **values)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None

    def numbers(self) -> dict[str, float]:
        """The number fields as a plain mapping (for summaries and logs)."""
        return {name: float(getattr(self, name)) for name in NUMBER_FIELDS}

    def describe(self) -> str:
        """One line for logs: every number field with its unit."""
        units = {"radius": "m", "v_max": "m/s", "w_max": "rad/s", "a_max": "m/s^2",
                 "alpha_max": "rad/s^2", "sensor_radius": "m", "power_weight": "m"}
        return ", ".join(f"{k} {v:g} {units[k]}" for k, v in self.numbers().items())


ROBOT_KEYS = frozenset(f.name for f in fields(RobotSpec))
LIDAR_KEYS = frozenset(f.name for f in fields(LidarSpec))
