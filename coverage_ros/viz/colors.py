"""Robot colours shared by every output (PNG, rerun), so robot 3 looks the same everywhere."""

from __future__ import annotations

import numpy as np

#: 20 well-separated RGB colours (a qualitative palette), cycled for larger teams.
PALETTE = np.array([
    [31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189],
    [140, 86, 75], [227, 119, 194], [127, 127, 127], [188, 189, 34], [23, 190, 207],
    [174, 199, 232], [255, 187, 120], [152, 223, 138], [255, 152, 150], [197, 176, 213],
    [196, 156, 148], [247, 182, 210], [199, 199, 199], [219, 219, 141], [158, 218, 229],
], dtype=np.uint8)


def robot_color(robot_id: int) -> np.ndarray:
    """``(3,) uint8`` RGB colour of a robot."""
    return PALETTE[int(robot_id) % len(PALETTE)]


def robot_colors(robot_ids) -> np.ndarray:
    """``(n, 3) uint8`` colours of several robots."""
    return PALETTE[np.asarray(robot_ids, dtype=np.int64) % len(PALETTE)]
