"""Checks that keep the layout honest: the core stays pure numpy/scipy, every folder is a real
package, modules stay small, and the shipped robot parameters file matches what robot_node
declares."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import yaml
from conftest import REPO

PACKAGE = REPO / "coverage_ros"
FORBIDDEN = ("rclpy", "pymunk", "rerun")
#: [lines] limit of a module's length: a module above it has more than one job.
MAX_MODULE_LINES = 400
#: [lines] modules longer than this are near the limit, and only a few may be.
NEAR_LIMIT_LINES, NEAR_LIMIT_MODULES = 360, 3


def test_every_core_module_imports_without_ros_pymunk_or_rerun():
    """Walk every module below coverage_ros/core (a new one is checked without editing this
    test) and import each in one fresh interpreter."""
    code = (
        "import importlib, json, pkgutil, sys\n"
        "import coverage_ros.core as core\n"
        "names = [m.name for m in pkgutil.walk_packages(core.__path__, 'coverage_ros.core.')]\n"
        "for name in names:\n"
        "    importlib.import_module(name)\n"
        f"bad = sorted(m for m in sys.modules if m.split('.')[0] in {FORBIDDEN!r})\n"
        "print(json.dumps({'modules': names, 'bad': bad}))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout.strip().splitlines()[-1])
    files = {p for p in (PACKAGE / "core").rglob("*.py")}
    # walk_packages lists the modules below coverage_ros.core, not the package itself.
    assert len(report["modules"]) + 1 == len(files), "a core file is not an importable module"
    assert report["bad"] == []


def test_every_source_folder_is_a_package():
    """Without __init__.py a folder is a namespace package: setuptools' find_packages skips it
    and an installed (non-editable) package would miss it."""
    folders = {p.parent for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts}
    missing = sorted(str(f.relative_to(REPO)) for f in folders
                     if not (f / "__init__.py").is_file())
    assert missing == []


def test_modules_stay_small():
    lengths = {str(p.relative_to(REPO)): len(p.read_text().splitlines())
               for p in PACKAGE.rglob("*.py")}
    assert {p: n for p, n in lengths.items() if n > MAX_MODULE_LINES} == {}
    near = {p: n for p, n in lengths.items() if n > NEAR_LIMIT_LINES}
    assert len(near) <= NEAR_LIMIT_MODULES, near


def test_generated_parameter_files_match_the_tables():
    """config/robot.yaml is what robot_node's table says (the documentation's parameter tables
    are made from the tables while the site builds: test/unit/docs/)."""
    from coverage_ros.nodes.reference import stale_files

    assert stale_files() == []


def test_robot_params_file_loads_as_the_declared_defaults():
    from coverage_ros.nodes.robot_parameters import PARAMETERS

    data = yaml.safe_load((REPO / "config" / "robot.yaml").read_text())
    shipped = data["/**"]["ros__parameters"]
    shipped.pop("use_sim_time")  # rclpy's own parameter
    assert shipped == {name: default for name, (default, _) in PARAMETERS.items()}
    assert all(type(shipped[n]) is type(d) for n, (d, _) in PARAMETERS.items())


def test_the_nodes_defaults_are_the_cores():
    """A robot_node parameter that configures a core object starts from that object's default."""
    from dataclasses import MISSING, fields

    from coverage_ros.core.control.controller import ControllerConfig
    from coverage_ros.core.strategies.base import StrategyContext
    from coverage_ros.nodes.robot_parameters import PARAMETERS

    shared = [(cls.__name__, f.name, f.default) for cls in (ControllerConfig, StrategyContext)
              for f in fields(cls) if f.name in PARAMETERS and f.default is not MISSING
              and f.name != "robot_id"]  # the node's -1: "from the namespace"
    assert len(shared) >= 6
    assert [(c, n, d) for c, n, d in shared if PARAMETERS[n][0] != d] == []


@pytest.mark.parametrize("module, forbidden", [
    ("coverage_ros.sim.world", ("rclpy", "rerun")),
    ("coverage_ros.cli.plan", ("rclpy", "rerun")),
    # A robot process carries what it needs and no more (the simulator and the viewer live in
    # other processes): every robot of a big team would pay for them in memory.
    ("coverage_ros.nodes.robot_node", ("pymunk", "rerun")),
    ("coverage_ros.nodes.robot_container", ("pymunk", "rerun")),
])
def test_processes_import_only_what_they_need(module, forbidden):
    code = (f"import sys, {module}; "
            f"bad = [m for m in sys.modules if m.split('.')[0] in {forbidden!r}]; "
            "print(bad); sys.exit(1 if bad else 0)")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True,
                         timeout=180)
    assert out.returncode == 0, out.stdout + out.stderr


def _module_imports() -> dict[str, set[str]]:
    """Every module of the package and the package modules it imports anywhere in its body
    (deferred imports inside functions included)."""
    import ast

    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(REPO).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                targets = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            graph[name] |= {t for t in targets if t in modules and t != name}
    return graph


def test_there_are_no_import_cycles():
    """No module imports, even late inside a function, a module that imports it back: a
    deferred import hides a cycle, it does not remove it."""
    graph = _module_imports()
    cycles = []
    done: set[str] = set()

    def visit(name: str, path: list[str]) -> None:
        if name in path:
            cycles.append(path[path.index(name):] + [name])
            return
        if name in done:
            return
        for nxt in sorted(graph[name]):
            visit(nxt, path + [name])
        done.add(name)

    for name in sorted(graph):
        visit(name, [])
    assert cycles == []
