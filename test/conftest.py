"""Shared test fixtures and helpers."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_MAPS = REPO.parent / "shared" / "maps"
WORLDS = REPO / "config" / "worlds"

# Every DDS process started by a test stays on this machine.
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

# Property tests draw the same examples on every run, so that CI passes or fails on the code,
# not on the draw; HYPOTHESIS_PROFILE=explore draws new, more examples to hunt for bugs.
try:
    from hypothesis import settings

    settings.register_profile("ci", derandomize=True)
    settings.register_profile("explore", max_examples=500)
    settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
except ImportError:  # hypothesis is a test dependency; tests that need it import it
    pass


def shared_map(name: str) -> Path:
    """Path of one of the real ROS maps in ../shared/maps (skips if the folder is absent)."""
    path = SHARED_MAPS / f"{name}.yaml"
    if not path.exists():
        pytest.skip(f"{path} not found (the shared maps live beside the repository)")
    return path


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(12345)
