"""One DDS domain per run, for sure: the launcher holds a lock on the domain id it runs on.

A lock is an ``flock`` on ``<lock dir>/domain-<id>.lock``; the kernel drops it when its owner
exits, however it exits, so a crashed launcher never blocks an id. A fresh id is one whose lock
this process gets *and* on which a short DDS probe sees no participant of someone else (a run
started by hand, a test, another stack on the same machine).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import random
import tempfile
import time
from pathlib import Path

from coverage_ros.errors import ConfigError

#: Fast DDS maps domain ids to UDP ports; 232 is the highest usable one.
MAX_DOMAIN_ID = 232
#: Where fresh ids are drawn from (0..99 are left to hand-made runs and other stacks).
FRESH_RANGE = (100, 199)
#: [s] how long a probe listens for foreign participants on a candidate domain.
PROBE_SECONDS = 0.6


def lock_dir() -> Path:
    path = Path(os.environ.get("COVERAGE_ROS_LOCK_DIR",
                               Path(tempfile.gettempdir()) / "coverage_ros-domains"))
    path.mkdir(parents=True, exist_ok=True)
    return path


class DomainLock:
    """A held lock on one domain id (released by :meth:`release` or by this process's exit)."""

    def __init__(self, domain_id: int, fd: int) -> None:
        self.domain_id = domain_id
        self._fd = fd

    def release(self) -> None:
        if self._fd >= 0:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = -1


def try_lock(domain_id: int) -> DomainLock | None:
    """The lock on ``domain_id`` if no other process holds it, else None."""
    fd = os.open(lock_dir() / f"domain-{domain_id}.lock", os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    return DomainLock(domain_id, fd)


def foreign_participants(domain_id: int, seconds: float = PROBE_SECONDS) -> list[str]:
    """Names of the ROS nodes seen on ``domain_id`` within ``seconds`` (discovery stays on
    this machine as the environment says)."""
    import rclpy

    # The probe looks at this machine only, like everything the launcher starts.
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id)
    try:
        node = rclpy.create_node("coverage_domain_probe", context=context,
                                 enable_rosout=False, start_parameter_services=False)
        deadline = time.monotonic() + seconds
        names: list[str] = []
        while time.monotonic() < deadline:
            names = [n for n in node.get_node_names() if n != "coverage_domain_probe"]
            if names:
                break
            time.sleep(0.1)
        node.destroy_node()
        return names
    finally:
        rclpy.try_shutdown(context=context)


def acquire_domain(requested: int | None, probe: bool = True) -> DomainLock:
    """The domain to run on, locked: ``requested`` (refused if another run holds it), else a
    fresh random id that no other run holds and, with ``probe``, where no node is seen."""
    if requested is not None:
        if not 0 <= requested <= MAX_DOMAIN_ID:
            raise ConfigError.at("--domain-id", f"must be in 0..{MAX_DOMAIN_ID}", requested)
        lock = try_lock(requested)
        if lock is None:
            raise ConfigError.at("--domain-id", "is in use by another coverage run on this "
                                 "machine", requested, "another id, or none for a fresh one")
        return lock
    ids = list(range(FRESH_RANGE[0], FRESH_RANGE[1] + 1))
    random.SystemRandom().shuffle(ids)
    for domain_id in ids:
        lock = try_lock(domain_id)
        if lock is None:
            continue
        if probe and foreign_participants(domain_id):
            lock.release()
            continue
        return lock
    raise ConfigError.at("--domain-id", "no free domain id left in "
                         f"{FRESH_RANGE[0]}..{FRESH_RANGE[1]}",
                         expected="fewer parallel runs, or --domain-id")
