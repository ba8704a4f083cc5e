"""world_node's parameters (:data:`PARAMETERS`, each declared once) and the configuration
they give, checked."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from coverage_ros.errors import ConfigError
from coverage_ros.nodes.world_lockstep import LockstepConfig
from coverage_ros.sim.world import SimConfig

PARAMETERS = {  # name: (default, description)
    "world": ("office", "a shipped world name (`config/worlds/<name>.yaml`, found through the "
                        "ament index share dir, else the source tree), or a path to a world YAML "
                        "or a map_server YAML"),
    "num_robots": (-1, "robots at start-up; `-1`: one per start pose of the world, or 4 if it "
                       "lists none"),
    "starts": ("", "start poses `x,y,yaw;x,y,yaw;...` [m, rad] overriding the world's; "
                   "`num_robots` -1 then means one robot per pose"),
    "team": ("", "team YAML (each robot's `id`, `start` and spec keys, e.g. `coverage-team`'s "
                 "`<out>/team.yaml`; docs: Reference, World and team files); overrides "
                 "`starts` and `num_robots`"),
    "seed": (0, "seeds placement, odometry noise and lidar noise: the same seed gives the same "
                "run"),
    "real_time_factor": (1.0, "sim seconds per wall second; `0`: as fast as possible"),
    "physics_rate_hz": (50.0, "fixed physics steps per simulated second"),
    "cmd_timeout": (0.5, "[s] sim time without `cmd_vel` after which a robot brakes to a stop "
                         "(within its acceleration limits)"),
    "use_stamped_cmd_vel": (False, "subscribe `geometry_msgs/TwistStamped` instead of `Twist`"),
    "odom_noise_trans": (0.0, "[m/sqrt(m)] odometry translation random walk: error std after "
                              "driving d metres is `k * sqrt(d)`"),
    "odom_noise_rot": (0.0, "[rad/sqrt(rad)] odometry heading random walk per radian turned"),
    "scan_noise_std": (-1.0, "[m] Gaussian lidar range noise; `< 0`: the world's "
                             "`lidar.noise_std`"),
    "odom_rate_hz": (20.0, "[Hz, sim time] rate of `odom` and `ground_truth`"),
    "clock_rate_hz": (0.0, "[Hz, sim time] rate of `/clock`; `0`: every physics step"),
    "status_rate_hz": (1.0, "[Hz, wall time] rate of `/world/robots`"),
    "robot_prefix": ("robot_", "robot namespaces and frame prefixes are `<prefix><id>`"),
    "publish_map": (True, "publish the true map on `/map`; `false` when the robots explore an "
                          "unknown map (the simulator still uses it)"),
    "publish_tf": (True, "publish `/tf` (`map -> robot_<id>/odom -> robot_<id>/base_link` per "
                         "robot) and `/tf_static` (`base_link -> base_scan`)"),
    "lockstep": (False, "lock-step (docs: Concepts, Lock-step): sim time advances one "
                        "`lockstep_period` only when every member - each robot with `lockstep: "
                        "true`, and the observers - has answered the last tick on "
                        "`/world/tick_report`; `/clock`, `odom` and `ground_truth` go out every "
                        "tick, `/world/robots` every `status_rate_hz` of sim time, and "
                        "`real_time_factor` > 0 caps the pace (0: as fast as the members answer)"),
    "lockstep_period": (0.1, "[s] sim time per tick (a whole number of physics steps); robots "
                             "track and command once per tick"),
    "lockstep_timeout": (10.0, "[s] wall time a member that owes an answer may stay silent "
                               "(robots send a heartbeat every second while they work) before the"
                               " world goes on without it, with one warning; it may join again"),
    "lockstep_start_timeout": (120.0, "[s] wall time the first tick waits for the robot of every "
                                      "body and for the `lockstep_observers`; then it starts with"
                                      " those that joined"),
    "lockstep_observers": ("", "comma-separated observer members the first tick waits for "
                               "(`coverage-team`'s monitor: `coverage_team`)"),
}
_DEFAULTS: dict[str, Any] = {name: default for name, (default, _) in PARAMETERS.items()}


@dataclass(frozen=True)
class WorldNodeConfig:
    """The node's parameters, validated (their meanings: :data:`PARAMETERS`)."""

    world: str = _DEFAULTS["world"]
    num_robots: int = _DEFAULTS["num_robots"]  # -1: the world's start poses, else 4
    real_time_factor: float = _DEFAULTS["real_time_factor"]
    use_stamped_cmd_vel: bool = _DEFAULTS["use_stamped_cmd_vel"]
    odom_rate_hz: float = _DEFAULTS["odom_rate_hz"]  # [Hz] sim time
    clock_rate_hz: float = _DEFAULTS["clock_rate_hz"]  # [Hz] sim time; 0: every physics step
    status_rate_hz: float = _DEFAULTS["status_rate_hz"]  # [Hz] wall time
    robot_prefix: str = _DEFAULTS["robot_prefix"]
    publish_map: bool = _DEFAULTS["publish_map"]
    publish_tf: bool = _DEFAULTS["publish_tf"]
    sim: SimConfig = field(default_factory=SimConfig)
    lockstep: LockstepConfig | None = None  # None: paced by the wall clock

    def __post_init__(self) -> None:
        if self.num_robots < -1:
            raise ConfigError.at("num_robots", "must be >= 0 (or -1: the world's robots)",
                                 self.num_robots)
        if not (math.isfinite(self.real_time_factor) and self.real_time_factor >= 0):
            raise ConfigError.at("real_time_factor", "must be >= 0 (0: as fast as possible)",
                                 self.real_time_factor)
        for name in ("odom_rate_hz", "status_rate_hz"):
            if not getattr(self, name) > 0:
                raise ConfigError.at(name, "must be > 0", getattr(self, name))
        if not self.clock_rate_hz >= 0:
            raise ConfigError.at("clock_rate_hz", "must be >= 0 (0: every physics step)",
                                 self.clock_rate_hz)
        if not self.robot_prefix or not self.robot_prefix.replace("_", "a").isalnum():
            raise ConfigError.at("robot_prefix", "must be letters, digits and '_'",
                                 self.robot_prefix)


@dataclass(frozen=True)
class WorldInputs:
    """The node's configuration and what places its robots at start-up: a team file, else
    start poses (``starts``, text), else the world's."""

    config: WorldNodeConfig
    starts: str
    team: str


def world_inputs(values: dict[str, Any]) -> WorldInputs:
    """The declared parameters' ``values``, checked (ConfigError names the parameter)."""
    p = dict(values)
    scan_noise = p.pop("scan_noise_std")
    starts_text = p.pop("starts")
    team_path = p.pop("team")
    lockstep: LockstepConfig | None = LockstepConfig(
        p.pop("lockstep_period"), p.pop("lockstep_timeout"), p.pop("lockstep_start_timeout"),
        tuple(n.strip() for n in p.pop("lockstep_observers").split(",") if n.strip()))
    if not p.pop("lockstep"):
        lockstep = None
    sim = SimConfig(seed=p.pop("seed"), physics_rate_hz=p.pop("physics_rate_hz"),
                    cmd_timeout=p.pop("cmd_timeout"),
                    odom_noise_trans=p.pop("odom_noise_trans"),
                    odom_noise_rot=p.pop("odom_noise_rot"),
                    scan_noise_std=scan_noise if scan_noise >= 0 else None)
    return WorldInputs(WorldNodeConfig(sim=sim, lockstep=lockstep, **p), starts_text, team_path)
