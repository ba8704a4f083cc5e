"""The nodes' parameter tables (:mod:`.parameters`) by node, and the file generated from them:
``config/robot.yaml``. ``python -m coverage_ros.nodes.reference --write`` rewrites it; without
``--write`` it exits 1 when it differs from its table (a test checks the same). The
documentation site's parameter tables are made from :func:`node_tables` while it builds
(:mod:`coverage_ros.docgen.pages`), so they need no writing.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

from coverage_ros.nodes.parameters import ParameterTable, params_file_text

REPO = Path(__file__).resolve().parents[2]
ROBOT_YAML = REPO / "config" / "robot.yaml"


def node_tables() -> dict[str, ParameterTable]:
    """Every node's table, by executable name."""
    from coverage_ros.nodes.bridge_config import PARAMETERS as BRIDGE
    from coverage_ros.nodes.marker_node import PARAMETERS as MARKERS
    from coverage_ros.nodes.robot_parameters import PARAMETERS as ROBOT
    from coverage_ros.nodes.world_config import PARAMETERS as WORLD

    return {"robot_node": ROBOT, "world_node": WORLD, "rerun_bridge": BRIDGE,
            "marker_node": MARKERS}


def generated_files() -> dict[Path, Callable[[str], str]]:
    """Each generated file and how its text now becomes what its tables say."""
    tables = node_tables()
    return {ROBOT_YAML: lambda _: params_file_text("robot_node", tables["robot_node"])}


def stale_files() -> list[Path]:
    """The generated files that differ from their tables."""
    return [path for path, make in generated_files().items()
            if path.read_text() != make(path.read_text())]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m coverage_ros.nodes.reference",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", action="store_true", help="rewrite the generated files")
    args = ap.parse_args(argv)
    if args.write:
        for path, make in generated_files().items():
            path.write_text(make(path.read_text()))
            print(f"wrote {path}")
        return 0
    stale = stale_files()
    for path in stale:
        print(f"{path}: differs from the parameter tables; run python -m "
              "coverage_ros.nodes.reference --write", file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
