"""One DDS domain per launcher run for sure: the domain locks
(coverage_ros/cli/team/domains.py)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from conftest import REPO

from coverage_ros.cli.team.domains import acquire_domain, try_lock
from coverage_ros.errors import ConfigError


@pytest.fixture(autouse=True)
def own_lock_dir(tmp_path, monkeypatch):
    """Locks of this test's runs only (the machine's real runs keep theirs)."""
    monkeypatch.setenv("COVERAGE_ROS_LOCK_DIR", str(tmp_path / "locks"))


def test_a_domain_lock_is_exclusive_and_dies_with_its_owner(tmp_path):
    lock = try_lock(150)
    assert lock is not None and try_lock(150) is None
    lock.release()
    again = try_lock(150)
    assert again is not None
    again.release()
    # A process that holds a lock and is killed (no clean-up at all) frees it.
    code = (f"import sys, time; sys.path.insert(0, {str(REPO)!r}); "
            "from coverage_ros.cli.team.domains import try_lock; l = try_lock(151); "
            "print('locked', flush=True); time.sleep(60)")
    holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                              env=dict(os.environ))
    try:
        assert holder.stdout.readline().strip() == "locked"
        assert try_lock(151) is None
        with pytest.raises(ConfigError, match="--domain-id: is in use by another coverage run"):
            acquire_domain(151)
    finally:
        holder.kill()
        holder.wait()
    assert try_lock(151) is not None
