"""The inverse sensor model of a planar lidar on an occupancy lattice: which cells one scan saw
free and which it saw occupied.

Per beam (REP 117 ranges):

* a finite return ``r`` in ``[range_min, range_max]``: the cells the beam crosses before ``r``
  are free, the cell holding the return point is occupied, nothing behind it is touched;
* ``+inf`` (no return within ``range_max``): free up to ``range_max``;
* ``-inf`` (closer than ``range_min``), NaN, or a return beyond ``range_max``: ignored;
* a return on another robot (within ``ignore_discs``): free up to it, but no obstacle - robots
  are not walls.

The robot's own footprint (:func:`footprint_cells`) is free ground: the robot stands on it.

Each cell counts at most once per scan (once free or once occupied; occupied wins), so a cell
crossed by many beams near the robot is not made more certain than one crossed by a single beam.

Vectorized: all beams are sampled at once every ``SAMPLE_STEP`` cells along their length and
the touched cells are collected by scattering into a boolean window the size of the scan's
reach (no per-beam Python loop; see :func:`reference_scan_cells` for the slow obvious version
the tests compare it with).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from coverage_ros.core.world.grid import GridMap

#: [cells] distance between samples along a beam: half a cell, so a beam crossing a cell by
#: more than half a cell's width is always caught (grazed corners may be missed, which only
#: leaves them unknown a little longer).
SAMPLE_STEP = 0.5
#: [cells] the return point is pushed this far along the beam, into the obstacle, so that a
#: return exactly on a cell border marks the obstacle's cell, not the free one before it.
HIT_PUSH = 0.01
#: [m] returns this close to a robot disc (beyond its radius) are that robot.
DISC_MARGIN = 0.1


@dataclass(frozen=True)
class ScanCells:
    """What one scan saw: flat cell indices (``row * W + col``) of the lattice."""

    free: np.ndarray  # (F,) int64, sorted, unique
    occupied: np.ndarray  # (O,) int64, sorted, unique, disjoint from ``free``


def scan_cells(lattice: GridMap, pose: np.ndarray, ranges: np.ndarray, angle_min: float,
               angle_increment: float, range_min: float, range_max: float,
               ignore_discs: np.ndarray | None = None) -> ScanCells:
    """The cells of ``lattice`` one scan saw free and occupied (see module docstring).

    ``pose`` (x [m], y [m], yaw [rad]) in the lattice's frame; ``ranges`` (B,) [m];
    ``ignore_discs`` (D, 3) ``(x, y, radius)`` of other robots."""
    pose = np.asarray(pose, dtype=np.float64)
    r = np.asarray(ranges, dtype=np.float64).ravel()
    angles = pose[2] + angle_min + angle_increment * np.arange(len(r))
    finite = np.isfinite(r) & (r >= range_min) & (r <= range_max)
    open_beam = np.isposinf(r)
    reach = np.where(finite, r, np.where(open_beam, range_max, 0.0))
    hit = finite.copy()
    direction = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    if ignore_discs is not None and len(ignore_discs) and hit.any():
        ends = pose[:2] + direction * reach[:, None]
        discs = np.asarray(ignore_discs, dtype=np.float64).reshape(-1, 3)
        d = np.hypot(ends[:, None, 0] - discs[None, :, 0], ends[:, None, 1] - discs[None, :, 1])
        hit &= ~np.any(d <= discs[None, :, 2] + DISC_MARGIN, axis=1)
    res = lattice.resolution
    H, W = lattice.shape
    g0 = lattice.world_to_grid(pose[:2])  # robot in grid coordinates (cells)
    gdir = lattice.direction_to_grid(direction)  # unit beam directions in grid axes
    reach_cells = reach / res
    longest = float(reach_cells.max(initial=0.0))
    # 1. A window of the lattice around the robot that holds every beam.
    pad = longest + 2.0
    c0, c1 = max(int(math.floor(g0[0] - pad)), 0), min(int(math.ceil(g0[0] + pad)) + 1, W)
    r0, r1 = max(int(math.floor(g0[1] - pad)), 0), min(int(math.ceil(g0[1] + pad)) + 1, H)
    if c0 >= c1 or r0 >= r1:
        return ScanCells(np.zeros(0, np.int64), np.zeros(0, np.int64))
    ww = c1 - c0
    # 2. Free samples: every SAMPLE_STEP cells along each beam, short of its end (the samples
    #    of all beams in one flat array: beam b has ceil((reach_b - HIT_PUSH) / step) of them).
    counts = np.maximum(np.ceil((reach_cells - HIT_PUSH) / SAMPLE_STEP), 0).astype(np.int64)
    beam = np.repeat(np.arange(len(counts)), counts)
    first = np.cumsum(counts) - counts
    t = (np.arange(len(beam)) - first[beam]) * SAMPLE_STEP
    free_w = _window_cells(g0[0] + gdir[beam, 0] * t, g0[1] + gdir[beam, 1] * t,
                           c0, c1, r0, r1)
    # 3. Returns: the cell just behind each obstacle return.
    th = reach_cells[hit] + HIT_PUSH
    hx, hy = g0[0] + gdir[hit, 0] * th, g0[1] + gdir[hit, 1] * th
    occ_w = _window_cells(hx, hy, c0, c1, r0, r1)
    # 4. Scatter into the window: each cell once; occupied wins over free.
    mark = np.zeros((r1 - r0) * ww, dtype=np.int8)
    mark[free_w] = 1
    mark[occ_w] = 2
    own = _window_cells(np.array([g0[0]]), np.array([g0[1]]), c0, c1, r0, r1)
    mark[own] = 1  # the robot stands on free ground
    free_local, occ_local = np.flatnonzero(mark == 1), np.flatnonzero(mark == 2)
    return ScanCells(_to_lattice(free_local, ww, c0, r0, W), _to_lattice(occ_local, ww, c0, r0, W))


def _window_cells(gx: np.ndarray, gy: np.ndarray, c0: int, c1: int, r0: int,
                  r1: int) -> np.ndarray:
    """Window-local flat indices of the grid points ``(gx, gy)`` that fall in the window."""
    cols = np.floor(gx).astype(np.int64)
    rows = np.floor(gy).astype(np.int64)
    ok = (cols >= c0) & (cols < c1) & (rows >= r0) & (rows < r1)
    local: np.ndarray = (rows[ok] - r0) * (c1 - c0) + (cols[ok] - c0)
    return local


def _to_lattice(local: np.ndarray, ww: int, c0: int, r0: int, W: int) -> np.ndarray:
    rows, cols = np.divmod(local, ww)
    nodes: np.ndarray = (rows + r0) * W + (cols + c0)
    return nodes


def reference_scan_cells(lattice: GridMap, pose: np.ndarray, ranges: np.ndarray,
                         angle_min: float, angle_increment: float, range_min: float,
                         range_max: float) -> ScanCells:
    """The same model written the slow obvious way: one beam at a time, a Python loop over
    its samples, sets of cells (for tests and the benchmark's reference)."""
    H, W = lattice.shape
    free: set[int] = set()
    occupied: set[int] = set()
    g0 = lattice.world_to_grid(np.asarray(pose[:2], dtype=np.float64))
    res = lattice.resolution

    def cell_of(gx: float, gy: float) -> int | None:
        c, r = math.floor(gx), math.floor(gy)
        return r * W + c if 0 <= r < H and 0 <= c < W else None

    for k, rng in enumerate(np.asarray(ranges, dtype=np.float64)):
        if math.isnan(rng) or rng == -math.inf or (math.isfinite(rng)
                                                   and not range_min <= rng <= range_max):
            continue
        is_hit = math.isfinite(rng)
        reach = (rng if is_hit else range_max) / res
        a = pose[2] + angle_min + angle_increment * k
        d = lattice.direction_to_grid(np.array([math.cos(a), math.sin(a)]))
        t = 0.0
        while t < reach - HIT_PUSH:
            cell = cell_of(g0[0] + d[0] * t, g0[1] + d[1] * t)
            if cell is not None:
                free.add(cell)
            t += SAMPLE_STEP
        if is_hit:
            cell = cell_of(g0[0] + d[0] * (reach + HIT_PUSH), g0[1] + d[1] * (reach + HIT_PUSH))
            if cell is not None:
                occupied.add(cell)
    own = cell_of(float(g0[0]), float(g0[1]))
    if own is not None:
        free.add(own)
        occupied.discard(own)
    free -= occupied
    return ScanCells(np.array(sorted(free), dtype=np.int64),
                     np.array(sorted(occupied), dtype=np.int64))


def footprint_cells(lattice: GridMap, xy: np.ndarray, radius: float) -> np.ndarray:
    """Flat indices (sorted) of the lattice cells under a disc robot of ``radius`` [m] at
    ``xy`` [m]: cells whose centre lies within ``radius`` + half a cell, the configuration
    space's own clearance (a planned robot centre keeps every blocked cell centre farther away
    than that), so the cells holding the edge of its body - where a teammate's lidar returns
    land - are included."""
    reach = float(radius) + 0.5 * lattice.resolution
    g = lattice.world_to_grid(np.asarray(xy, dtype=np.float64).reshape(2))
    span = reach / lattice.resolution
    H, W = lattice.shape
    c0, c1 = max(int(math.floor(g[0] - span)), 0), min(int(math.ceil(g[0] + span)) + 1, W)
    r0, r1 = max(int(math.floor(g[1] - span)), 0), min(int(math.ceil(g[1] + span)) + 1, H)
    if c0 >= c1 or r0 >= r1:
        return np.zeros(0, np.int64)
    cols, rows = np.meshgrid(np.arange(c0, c1), np.arange(r0, r1))
    # Cell (col, row) has its centre at grid coordinates (col + 0.5, row + 0.5).
    d = np.hypot(cols + 0.5 - g[0], rows + 0.5 - g[1]) * lattice.resolution
    inside = d <= reach
    return np.sort(rows[inside].astype(np.int64) * W + cols[inside])
