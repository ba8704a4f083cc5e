"""Shared test fixtures and helpers, and the markers a test's folder gives it.

test/unit/ mirrors coverage_ros/ (a test sits under the part it tests); test/integration/ holds
the tests that start real node processes and talk to them over DDS - each of them is marked
``integration`` here, by its folder, never in the file. ``lockstep`` (a live team in lock-step,
which may run beside other tests) and ``slow`` stay on the tests themselves.
"""

from __future__ import annotations

import os
import sys
import sysconfig
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
REPO = TESTS.parent
SHARED_MAPS = REPO.parent / "shared" / "maps"
WORLDS = REPO / "config" / "worlds"
#: The team options of a geodesic team without its closet escape, for tests of something else: a
#: settled team prices moves at nearly every update (about 15x the CPU on tb3_sandbox), while
#: the escape has its own tests (test_handover.py, test_team.py's geodesic team).
NO_ESCAPE = ("--strategy-params", "{escape: false}")

# Every DDS process started by a test stays on this machine.
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

# Property tests draw the same examples on every run, so that CI passes or fails on the code,
# not on the draw; HYPOTHESIS_PROFILE=explore draws new, more examples to hunt for bugs. No
# deadline and no too_slow health check: an example's time says how busy the machine is, not
# whether the code is right (hypothesis's 200 ms deadline failed a 0.2 ms frame composition on a
# loaded CI machine).
try:
    from hypothesis import HealthCheck, settings

    timing = {"deadline": None, "suppress_health_check": [HealthCheck.too_slow]}
    settings.register_profile("ci", derandomize=True, **timing)
    settings.register_profile("explore", max_examples=500, **timing)
    settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
except ImportError:  # hypothesis is a test dependency; tests that need it import it
    pass


def shared_map(name: str) -> Path:
    """Path of one of the real ROS maps in ../shared/maps (skips if the folder is absent)."""
    path = SHARED_MAPS / f"{name}.yaml"
    if not path.exists():
        pytest.skip(f"{path} not found (the shared maps live beside the repository)")
    return path


def random_points(domain, n_free: int, n_blocked: int, seed: int):
    """``(n_free + n_blocked, 2)`` [m] random free points of a CoverageDomain, then points on
    blocked cells (robots inside the inflated margin), 0.2 m inside its extent."""
    import numpy as np

    rng = np.random.default_rng(seed)
    xmin, ymin, xmax, ymax = domain.geometry.extent()
    free, blocked = [], []
    while len(free) < n_free or len(blocked) < n_blocked:
        p = rng.uniform([xmin + 0.2, ymin + 0.2], [xmax - 0.2, ymax - 0.2])
        (free if domain.is_free_point(p) else blocked).append(p)
    return np.array(free[:n_free] + blocked[:n_blocked])


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(12345)


def entry_point(name: str) -> str:
    """Path of the console script ``name`` (coverage-team, coverage-plan, world_node, rerun ...)
    of the Python environment running the tests, where ``pip install -e .`` put it."""
    folders = list(dict.fromkeys([Path(sysconfig.get_path("scripts")),
                                  Path(sys.executable).parent]))
    for folder in folders:
        path = folder / name
        if path.is_file() and os.access(path, os.X_OK):
            return str(path)
    pytest.fail(f"console script {name!r} not found in {' or '.join(map(str, folders))}: "
                f"coverage_ros is not installed into the Python running the tests "
                f"({sys.executable}). ./scripts/test sets up .venv with everything installed; "
                f"in another environment run `pip install -e .` from {REPO}", pytrace=False)


def _kind(path: Path) -> str:
    """``unit`` or ``integration``: the top folder of a test file below test/."""
    parts = path.resolve().relative_to(TESTS).parts
    return parts[0] if len(parts) > 1 else ""


@pytest.hookimpl(tryfirst=True)  # before -m deselects by marker
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Every test under test/integration gets ``integration``; a test elsewhere that says it is
    one, a lock-step test outside integration, or a test file outside both folders is a
    mistake that would put the test in the wrong phase of scripts/test. Files with ``slow``
    tests run first."""
    wrong = []
    for item in items:
        kind = _kind(Path(item.path))
        if kind not in ("unit", "integration"):
            wrong.append(f"{item.nodeid}: test files live in test/unit or test/integration")
        elif item.get_closest_marker("integration") is not None:
            wrong.append(f"{item.nodeid}: an integration test is one in test/integration "
                         "(the folder marks it; no explicit mark)")
        elif kind == "unit" and item.get_closest_marker("lockstep") is not None:
            wrong.append(f"{item.nodeid}: lockstep marks a live team's test, in "
                         "test/integration")
        if kind == "integration":
            item.add_marker(pytest.mark.integration)
    if wrong:
        raise pytest.UsageError("\n".join(wrong))
    # The files with slow tests first, each file's tests together (its module fixtures): on
    # the xdist workers the run then does not end with one long test that started last.
    slow_files = {item.path for item in items if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: item.path not in slow_files)

