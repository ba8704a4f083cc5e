"""Reading rerun recordings back in tests (what a user's viewer would show)."""

from __future__ import annotations

import subprocess

import numpy as np
from conftest import entry_point


def read_rrd(path) -> dict[str, list[tuple[float | None, dict]]]:
    """``{entity: [(sim_time [s] or None if static, {component: value}), ...]}``, time-sorted."""
    from rerun.chunk import RrdReader

    rows: dict[str, list] = {}
    for chunk in RrdReader(path).store().stream():
        batch = chunk.to_record_batch()
        names = batch.schema.names
        times = (batch.column("sim_time").cast("int64").to_pylist() if "sim_time" in names
                 else [None] * batch.num_rows)
        batch = batch.drop_columns([n for n in ("log_time", "sim_time") if n in names])
        for t, row in zip(times, batch.to_pylist(), strict=True):
            rows.setdefault(chunk.entity_path, []).append((None if t is None else t * 1e-9, row))
    for entries in rows.values():
        entries.sort(key=lambda e: -1.0 if e[0] is None else e[0])
    return rows


def cell_rgba(row: dict) -> np.ndarray:
    """``(H, W, 4)`` cell layer of a /world/cells row, flipped back to ROS row order."""
    fmt = row["GridMap:format"][0]
    data = np.array(row["GridMap:data"][0], dtype=np.uint8)
    return np.flipud(data.reshape(fmt["height"], fmt["width"], 4))


def rerun_verify(path) -> subprocess.CompletedProcess:
    """``rerun rrd verify`` (rerun-sdk's command line) on the recording at ``path``."""
    return subprocess.run([entry_point("rerun"), "rrd", "verify", str(path)],
                          capture_output=True, text=True, timeout=180)
