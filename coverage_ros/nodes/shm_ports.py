"""Fast DDS shared-memory ports that a killed process left half made.

Fast DDS (rmw_fastrtps) gives each DDS participant on a machine shared-memory "ports": files
``/dev/shm/fastrtps_port<N>`` that it creates, sizes and then marks initialised. A process
killed between the creation and the mark leaves a file that every later participant needing
port N opens and then waits on for ever, inside ``rclpy.init`` or the first node's creation:
the process hangs without a word (eProsima/Fast-DDS#3878). :func:`remove_broken_ports`,
called by every executable of this package before it starts ROS, removes such files: one still
unsized or unmarked :data:`STALE_AGE` seconds after its last change is broken (a live creator
takes microseconds). Participants re-create a removed port as they need it. A process already
waiting cannot be helped from inside (the wait holds the GIL): the team launcher starts such a
child again (:func:`held_broken_ports`, ``ProcessSet.restart_stuck``).

A process started again in place of a killed one keeps off shared memory
(:func:`restarted_env`): Fast DDS gives its participant the killed one's port number, and a
listener that takes over a dead port's file can leave the live processes writing into the
segment they had mapped before, so the new process hears nothing from them - no map, no clock -
while they hear it (eProsima/Fast-DDS#5053, #4728).
"""

from __future__ import annotations

import os
import re
import sys
import time
from pathlib import Path

SHM_DIR = Path("/dev/shm")
#: [s] age after which an unsized or unmarked port file is taken as abandoned (its creator
#: sizes and marks it within milliseconds, even on a loaded machine).
STALE_AGE = 3.0
_PORT_NAME = re.compile(r"fastrtps_port\d+")
#: boost.interprocess's segment header: a 32-bit state first, ``2`` once initialised
#: (0 not yet, 1 initialising, 3 corrupted).
_INITIALISED = 2


def _is_broken(path: Path) -> bool:
    """Unsized, or its header not marked initialised (OSError if it cannot be read)."""
    if path.stat().st_size < 4:
        return True
    with open(path, "rb") as fh:
        return int.from_bytes(fh.read(4), "little") != _INITIALISED


def broken_ports(shm_dir: Path | None = None, now: float | None = None) -> list[Path]:
    """Port files in ``shm_dir`` (default :data:`SHM_DIR`) that a participant would wait on for
    ever (module docstring)."""
    shm_dir = SHM_DIR if shm_dir is None else shm_dir
    now = time.time() if now is None else now
    broken = []
    try:
        candidates = [p for p in shm_dir.iterdir() if _PORT_NAME.fullmatch(p.name)]
    except OSError:  # (no such folder: not Linux)
        return []
    for path in candidates:
        try:
            if now - path.stat().st_mtime >= STALE_AGE and _is_broken(path):
                broken.append(path)
        except OSError:  # (gone meanwhile, or not ours to read)
            continue
    return broken


def restarted_env(env: dict[str, str]) -> dict[str, str]:
    """What to add to ``env`` for a process started in place of a killed one: Fast DDS on UDP
    alone (module docstring), unless ``env`` already chooses its transports."""
    if "FASTDDS_BUILTIN_TRANSPORTS" in env:
        return {}
    return {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}


def held_broken_ports(fd_dir: Path = Path("/proc/self/fd")) -> list[Path]:
    """Broken port files this process has open (``fd_dir``: its open files): a process that
    has waited on one for a while is stuck there for good."""
    held = []
    try:
        links = list(fd_dir.iterdir())
    except OSError:
        return []
    for link in links:
        try:
            target = Path(os.readlink(link))
            if _PORT_NAME.fullmatch(target.name) and _is_broken(target):
                held.append(target)
        except OSError:
            continue
    return held


def remove_broken_ports(shm_dir: Path | None = None, now: float | None = None) -> list[str]:
    """Remove :func:`broken_ports`; the names of those removed."""
    removed = []
    for path in broken_ports(shm_dir, now):
        try:
            path.unlink()
        except OSError:
            continue
        removed.append(path.name)
    return removed


def warn_removed_ports(program: str) -> None:
    """:func:`remove_broken_ports`, with one line on stderr naming them if there were any."""
    removed = remove_broken_ports()
    if removed:
        print(f"{program}: warning: removed {len(removed)} broken Fast DDS shared-memory "
              f"file(s) that a killed process left in {SHM_DIR} ({', '.join(removed[:4])})",
              file=sys.stderr)


def startup_hint() -> str:
    """For a start-up timeout's message: removes :func:`broken_ports` and, if there were any,
    says that they hang a starting process (those that started meanwhile wait on for ever)."""
    removed = remove_broken_ports()
    if not removed:
        return ""
    return (f"; {len(removed)} broken Fast DDS shared-memory file(s) in {SHM_DIR}, which make a "
            f"starting process wait for ever, were removed ({', '.join(removed[:4])}): run "
            f"again")
