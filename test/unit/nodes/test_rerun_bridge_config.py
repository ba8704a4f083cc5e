"""The rerun bridge's settings, checked before it starts (coverage_ros/nodes/rerun_bridge.py);
the real node streaming a team: integration/test_rerun_bridge.py."""

from __future__ import annotations

import os
import subprocess

import pytest
from conftest import REPO, entry_point
from rosutil import domain_id


def test_config_is_validated():
    pytest.importorskip("rclpy")
    from coverage_ros.errors import ConfigError
    from coverage_ros.nodes.bridge_config import BridgeConfig

    assert BridgeConfig(record_path="x.rrd").rates().scan_decimation == 2
    for kwargs, message in [
        ({}, "no output"),
        ({"record_path": "/nonexistent/dir/x.rrd"}, "folder does not exist"),
        ({"connect_url": "http://localhost:9876"}, "rerun gRPC URL"),
        ({"serve_web": True, "web_port": 9876}, "must differ"),
        ({"record_path": "x.rrd", "metrics_period": -1.0}, "metrics_period"),
        ({"record_path": "x.rrd", "scan_decimation": 0}, "scan_decimation"),
        ({"record_path": "x.rrd", "robot_prefix": "robot/"}, "robot_prefix"),
    ]:
        with pytest.raises(ConfigError, match=message):
            BridgeConfig(**kwargs)


def test_ros2_run_layout_has_the_console_script():
    exe = REPO / "install" / "coverage_ros" / "lib" / "coverage_ros" / "rerun_bridge"
    assert exe.exists(), "colcon's ros2 run layout has the console script"
    out = subprocess.run([entry_point("rerun_bridge")], capture_output=True,
                         text=True, timeout=180,
                         env={**os.environ, "ROS_DOMAIN_ID": str(domain_id(22)),
                              "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    assert out.returncode == 2
    assert out.stderr.strip() == ("rerun_bridge: error: record_path: no output: set "
                                  "record_path, connect_url or serve_web (got '')")
