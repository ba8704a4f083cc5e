"""rerun_bridge's parameters (:data:`PARAMETERS`, each declared once) and the configuration
they give, checked."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path as FilePath
from typing import Any

from coverage_ros.core.world import RobotSpec
from coverage_ros.errors import ConfigError

PARAMETERS = {  # name: (default, description)
    "record_path": ("", "write the recording to this `.rrd` file (its folder must exist)"),
    "record_index": (True, "when the bridge stops, rewrite the file compacted and ending with "
                           "rerun's chunk index (`rerun rrd optimize`, into a file beside it, "
                           "then swapped in)"),
    "connect_url": ("", "stream to a running viewer, e.g. `rerun+http://127.0.0.1:9876/proxy`"),
    "serve_web": (False, "host a web viewer and its gRPC proxy on 127.0.0.1"),
    "web_port": (9090, "HTTP port of the web viewer (`serve_web`)"),
    "grpc_port": (9876, "gRPC port of the web viewer's proxy (`serve_web`)"),
    "robot_prefix": ("robot_", "robot namespaces are `/<prefix><id>`"),
    "recording_id": ("", "rerun recording id; processes with the same id share one recording; "
                         "`\"\"`: a new random id"),
    "world": ("", "world name or YAML for the importance-density layer and the metrics; `\"\"`: "
                  "uniform density"),
    "robot_radius": (RobotSpec().radius,
                     "[m] robot markers and the inflation of the metrics' map"),
    "metrics_period": (1.0, "[s, sim time] between H / cell-mass computations; `0`: none"),
    "cells_period": (0.5, "[s, sim time] between cell-layer updates; `0`: on every change"),
    "robots_period": (0.1, "[s, sim time] between robot-marker updates; `0`: every pose"),
    "trajectory_period": (0.5, "[s, sim time] between trajectory points; `0`: every pose"),
    "scan_period": (0.5, "[s, sim time] between logged scans of a robot; `0`: every scan"),
    "scan_decimation": (2, "log every n-th lidar hit"),
    "computed_cells": (True, "until a robot publishes its own cell, show the cells of the "
                             "metrics' tessellation"),
    "explore": (False, "the team explores an unknown map: show the world's true map, the team's "
                       "merged belief as an entropy layer over it (white: unknown), and the "
                       "explored fraction and false free share as plots; needs `world`"),
}
_DEFAULTS: dict[str, Any] = {name: default for name, (default, _) in PARAMETERS.items()}


@dataclass(frozen=True)
class BridgeConfig:
    """The node's parameters, validated (meanings: PARAMETERS and README)."""

    record_path: str = _DEFAULTS["record_path"]
    record_index: bool = _DEFAULTS["record_index"]
    connect_url: str = _DEFAULTS["connect_url"]
    serve_web: bool = _DEFAULTS["serve_web"]
    web_port: int = _DEFAULTS["web_port"]
    grpc_port: int = _DEFAULTS["grpc_port"]
    robot_prefix: str = _DEFAULTS["robot_prefix"]
    recording_id: str = _DEFAULTS["recording_id"]
    world: str = _DEFAULTS["world"]
    robot_radius: float = _DEFAULTS["robot_radius"]
    metrics_period: float = _DEFAULTS["metrics_period"]
    cells_period: float = _DEFAULTS["cells_period"]
    robots_period: float = _DEFAULTS["robots_period"]
    trajectory_period: float = _DEFAULTS["trajectory_period"]
    scan_period: float = _DEFAULTS["scan_period"]
    scan_decimation: int = _DEFAULTS["scan_decimation"]
    computed_cells: bool = _DEFAULTS["computed_cells"]
    explore: bool = _DEFAULTS["explore"]

    def __post_init__(self) -> None:
        if not (self.record_path or self.connect_url or self.serve_web):
            raise ConfigError.at("record_path", "no output: set record_path, connect_url or "
                                 "serve_web", self.record_path)
        if self.record_path and not FilePath(self.record_path).expanduser().parent.is_dir():
            raise ConfigError.at("record_path", "folder does not exist", self.record_path)
        if self.connect_url and not self.connect_url.startswith(
                ("rerun://", "rerun+http://", "rerun+https://")):
            raise ConfigError.at("connect_url", "must be a rerun gRPC URL", self.connect_url,
                                 "rerun+http://127.0.0.1:9876/proxy")
        for name in ("web_port", "grpc_port"):
            if not 1 <= getattr(self, name) <= 65535:
                raise ConfigError.at(name, "must be a TCP port 1..65535", getattr(self, name))
        if self.serve_web and self.web_port == self.grpc_port:
            raise ConfigError.at("web_port", "must differ from grpc_port", self.web_port)
        if not self.robot_prefix or not self.robot_prefix.replace("_", "a").isalnum():
            raise ConfigError.at("robot_prefix", "must be letters, digits and '_'",
                                 self.robot_prefix)
        if not (math.isfinite(self.robot_radius) and self.robot_radius > 0):
            raise ConfigError.at("robot_radius", "must be a number > 0", self.robot_radius)
        for name in ("metrics_period", "cells_period", "robots_period", "trajectory_period",
                     "scan_period"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError.at(name, "must be a number of seconds >= 0", value)
        if self.scan_decimation < 1:
            raise ConfigError.at("scan_decimation", "must be >= 1", self.scan_decimation)
        if self.explore and not self.world:
            raise ConfigError.at("explore", "needs 'world': the true map to score the team's "
                                 "belief against", self.world)

    def rates(self):
        """The layers' settings (:class:`coverage_ros.viz.live_team.LiveRates`)."""
        from coverage_ros.viz.live_team import LiveRates

        return LiveRates(self.robots_period, self.trajectory_period, self.scan_period,
                         self.cells_period, self.metrics_period, self.scan_decimation,
                         self.robot_radius, self.computed_cells)
