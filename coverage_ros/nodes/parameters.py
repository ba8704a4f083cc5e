"""The nodes' parameters, each declared once: every node keeps one table ``{name: (default,
description)}`` (the description starts with the unit in brackets where there is one). The
table is what the node declares; from it :mod:`.reference` writes ``config/robot.yaml`` and
the documentation site's reference shows :func:`markdown_table` of it.
"""

from __future__ import annotations

import json
import textwrap
from collections.abc import Mapping
from typing import Any

ParameterTable = Mapping[str, tuple[object, str]]

def declare_parameters(node, table: ParameterTable) -> dict[str, Any]:
    """Declare ``{name: (default, description)}`` on the rclpy ``node``; the values it was
    given. A value of the wrong type raises ParameterException (a start-up error)."""
    from rcl_interfaces.msg import ParameterDescriptor

    for name, (default, text) in table.items():
        node.declare_parameter(name, default, ParameterDescriptor(description=text))
    return {name: node.get_parameter(name).value for name in table}


def yaml_value(value: object) -> str:
    """``value`` as YAML that reads back as exactly it (strings quoted)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(value)


def params_file_text(node: str, table: ParameterTable) -> str:
    """A ROS parameters file of every parameter of ``table`` at its default, each after its
    description, for nodes of any name and namespace (``/**``)."""
    lines = [f"# {node} parameters, each at its default (generated from the node's table: "
             "python -m coverage_ros.nodes.reference --write).",
             f"#   ros2 run coverage_ros {node} --ros-args -r __ns:=/robot_3 "
             "--params-file config/robot.yaml",
             "/**:", "  ros__parameters:"]
    for name, (default, text) in table.items():
        lines += textwrap.wrap(text, 95, initial_indent="    # ", subsequent_indent="    # ")
        lines.append(f"    {name}: {yaml_value(default)}")
    lines += ["    # run on the simulator's /clock (rclpy's own parameter)",
              "    use_sim_time: true"]
    return "\n".join(lines) + "\n"


def markdown_table(table: ParameterTable) -> str:
    """The reference table of a node's parameters: name, default, meaning."""
    rows = ["| name | default | meaning |", "|---|---|---|"]
    for name, (default, text) in table.items():
        if isinstance(default, str):
            shown = default or "''"
        else:
            shown = yaml_value(default)
        meaning = text.replace("|", r"\|")
        rows.append(f"| `{name}` | `{shown}` | {meaning} |")
    return "\n".join(rows)


def usage_text(node: str, table: ParameterTable) -> str:
    """``--help`` of node executable ``node``: how to start it, and its parameters (name,
    default, meaning)."""
    lines = [f"usage: ros2 run coverage_ros {node} [--ros-args -p NAME:=VALUE ... "
             "| --params-file FILE]"]
    if table:
        width = max(len(k) for k in table)
        lines += ["", "parameters:"] + [f"  {k:<{width}}  {yaml_value(d)}: {text}"
                                        for k, (d, text) in table.items()]
    return "\n".join(lines)
