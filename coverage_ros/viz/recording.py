"""Rerun recordings of coverage runs (offline plans and live teams).

Entity layout (all in the ``map`` frame, metres, z = 0 is the floor)::

    /world/map            GridMap, static: free white, obstacles dark, unknown grey
    /world/density        GridMap, static: importance density (viridis), under the cells
    /world/entropy        GridMap: exploring, the team's belief entropy (white: unknown)
    /world/cells          GridMap: every robot's cell in the robot's colour
    /world/robots         Points3D: robot positions (labels "robot_<id>", robot colours)
    /world/goals          Points3D: current goals
    /world/trajectories/robot_<id>   LineStrips3D: path driven so far
    /world/plans/robot_<id>          LineStrips3D: planned path
    /world/scans/robot_<id>          Points3D: lidar hits
    /world/cell_polygons/robot_<id>  LineStrips3D: cell outline (strategies that publish one)
    /world/region         LineStrips3D: the region of interest (README "Using it on your robots")
    /metrics/H            Scalars: coverage cost
    /metrics/mass/robot_<id>         Scalars: cell masses
    /metrics/explored     Scalars: exploring, explored fraction and false free share
    /state/robot_<id>     Scalars: a robot's coverage_state values, a series per name
    /status/robot_<id>    Scalars: the simulator's per-robot counters (and /status/world)

A live trajectory is logged in pieces: the growing tail at ``/world/trajectories/robot_<id>``
and each finished piece once at ``/world/trajectories/robot_<id>/part_<k>`` (see
:class:`coverage_ros.viz.team.Trajectory`); offline plans log the whole path at the first.

A rerun ``GridMap`` draws its data row 0 at the top and is placed by its lower-left corner,
so ROS-convention grids (row 0 at the origin) are flipped here. Grid maps only render in 3-D
views; the default blueprint looks at the floor from above.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import uuid
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from coverage_ros.core.world.grid import GridMap
from coverage_ros.viz.colors import robot_color, robot_colors

APP_ID = "coverage_ros"
TIMELINE = "sim_time"
CELL_OPACITY = 0.45  # cells tint the map without hiding it
DENSITY_OPACITY = 0.35
Z_MAP, Z_DENSITY, Z_ENTROPY, Z_CELLS = 0.0, 0.001, 0.0015, 0.002  # [m] draw order along z
ENTROPY_OPACITY = 0.6  # over the true map: unknown shows white, explored shows the map
ROBOT_HEIGHT = 0.05  # [m] robots and paths float just above the map
FLUSH_TIMEOUT = 10.0  # [s] wall time to hand buffered data to the sinks at the end


def _rr():
    import rerun as rr  # local: only the viz layer needs rerun

    return rr


def map_rgb(grid: GridMap) -> np.ndarray:
    """``(H, W, 3) uint8`` picture of an occupancy grid in ROS row order."""
    occ = grid.occupancy
    rgb = np.full(occ.shape + (3,), 255, dtype=np.uint8)
    rgb[occ < 0] = (150, 150, 150)
    rgb[occ >= 65] = (30, 30, 30)
    return rgb


def cells_rgba(labels: np.ndarray, robot_ids=None) -> np.ndarray:
    """``(H, W, 4) uint8``: label ``k >= 0`` in robot ``robot_ids[k]``'s colour, transparent
    where ``labels < 0``."""
    lab = np.asarray(labels)
    out = np.zeros(lab.shape + (4,), dtype=np.uint8)
    own = lab >= 0
    ids = np.arange(int(lab.max()) + 1 if own.any() else 0) if robot_ids is None \
        else np.asarray(robot_ids)
    if own.any():
        out[own, :3] = robot_colors(ids[lab[own]])
        out[own, 3] = 255
    return out


class CoverageRecorder:
    """Writes the entities above to one rerun recording stream."""

    def __init__(self, recording_id: str | None = None, application_id: str = APP_ID,
                 batch_period: float | None = None):
        """``batch_period`` [s]: how long rows are collected into one chunk before they are
        sent (None: rerun's default, 0.2 s); longer means fewer, larger chunks."""
        rr = _rr()
        self.rr = rr
        self.recording_id = recording_id or str(uuid.uuid4())
        batcher = None if batch_period is None else rr.ChunkBatcherConfig(
            flush_tick=float(batch_period))
        self.stream = rr.RecordingStream(application_id, recording_id=self.recording_id,
                                         batcher_config=batcher)
        self._grid: GridMap | None = None
        self._series: dict[str, list[str]] = {}  # entity -> series names (log_values)
        self._last_cells: np.ndarray | None = None  # RGBA of the last cell layer logged
        self.exploring = False  # an entropy layer was logged: show the explored plot

    # ------------------------------------------------------------------ sinks
    def save(self, path: str | Path) -> None:
        self.stream.save(str(path), default_blueprint=self.blueprint())

    def set_outputs(self, record_path: str | Path | None = None,
                    connect_urls: Iterable[str] = (), footer: bool = True) -> None:
        """Write to a file and/or stream to viewers (gRPC), all at once. ``footer``: end the
        file with rerun's chunk index, which rerun keeps in memory until then (it grows with
        every chunk: leave it out for live recordings of unbounded length)."""
        rr = self.rr
        sinks = [rr.GrpcSink(url) for url in connect_urls]
        if record_path:
            sinks.insert(0, rr.FileSink(str(record_path), write_footer=footer))
        self.stream.set_sinks(*sinks, default_blueprint=self.blueprint())

    def send_blueprint(self) -> None:
        """Make the current :meth:`blueprint` (e.g. now looking at the map) the active one."""
        self.stream.send_blueprint(self.blueprint(), make_active=True, make_default=True)

    def flush(self) -> None:
        self.stream.flush(timeout_sec=FLUSH_TIMEOUT)

    def close(self) -> None:
        """Flush and close every sink (a file gets its footer and is complete); raises if a
        sink failed (e.g. a viewer went away), after closing the others."""
        try:
            self.flush()
        finally:
            self.stream.disconnect()

    def blueprint(self):
        import rerun.blueprint as rrb

        eye = None
        if self._grid is not None:
            x0, y0, x1, y1 = self._grid.extent()
            cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
            height = 1.1 * max(x1 - x0, y1 - y0)
            eye = rrb.EyeControls3D(position=(cx, cy, height), look_target=(cx, cy, 0.0),
                                    eye_up=(0.0, 1.0, 0.0))
        view = rrb.Spatial3DView(origin="/world", name="map and cells", eye_controls=eye)
        plots = [rrb.TimeSeriesView(origin="/metrics/H", name="coverage cost H"),
                 rrb.TimeSeriesView(origin="/metrics/mass", name="cell masses")]
        if self.exploring:
            plots.insert(0, rrb.TimeSeriesView(origin="/metrics/explored", name="explored"))
        return rrb.Blueprint(
            rrb.Horizontal(view, rrb.Vertical(*plots), column_shares=[3, 1]),
            # "following": a saved recording opens at its end, on the team (not on an empty
            # map at its first second); a live one follows the newest data.
            rrb.TimePanel(timeline=TIMELINE, play_state="following"), collapse_panels=True)

    # ------------------------------------------------------------------ static layers
    def _grid_map(self, grid: GridMap, rgb: np.ndarray, channels: str):
        rr = self.rr
        data = np.ascontiguousarray(np.flipud(rgb))
        fmt = rr.components.ImageFormat(width=grid.width, height=grid.height,
                                        color_model=channels, channel_datatype="U8")
        return data, fmt

    def log_map(self, grid: GridMap, density: np.ndarray | None = None) -> None:
        rr = self.rr
        self._grid = grid
        x0, y0 = grid.origin[0], grid.origin[1]
        data, fmt = self._grid_map(grid, map_rgb(grid), "RGB")
        self.stream.log("/world/map", rr.GridMap(data=data.tobytes(), format=fmt,
                                                 cell_size=grid.resolution,
                                                 translation=[x0, y0, Z_MAP]), static=True)
        if density is not None:
            self.log_density(grid, density)

    def log_density(self, grid: GridMap, density: np.ndarray) -> None:
        """The ``(H, W)`` density on ``grid`` (static; nothing for a uniform density)."""
        rr = self.rr
        x0, y0 = grid.origin[0], grid.origin[1]
        if np.ptp(density) > 0:
            w = np.asarray(density, dtype=np.float64)
            scaled = (255.0 * (w - w.min()) / max(np.ptp(w), 1e-12)).astype(np.uint8)
            self.stream.log("/world/density", rr.GridMap(
                data=np.ascontiguousarray(np.flipud(scaled)).tobytes(),
                format=rr.components.ImageFormat(width=grid.width, height=grid.height,
                                                 color_model="L", channel_datatype="U8"),
                cell_size=grid.resolution, translation=[x0, y0, Z_DENSITY],
                colormap=rr.components.Colormap.Viridis, opacity=DENSITY_OPACITY),
                static=True)

    def log_entropy(self, grid: GridMap, entropy: np.ndarray) -> None:
        """The ``(H, W)`` belief entropy [nats] on ``grid`` at the current time: white where
        nothing is known (ln 2), transparent where the map is decided."""
        rr = self.rr
        if not self.exploring:
            self.exploring = True
            self.send_blueprint()  # with the explored-fraction plot
        e = np.clip(np.asarray(entropy, dtype=np.float64) / np.log(2.0), 0.0, 1.0)
        rgba = np.zeros(e.shape + (4,), np.uint8)
        rgba[..., :3] = 255
        rgba[..., 3] = (255.0 * ENTROPY_OPACITY * e).astype(np.uint8)
        data, fmt = self._grid_map(grid, rgba, "RGBA")
        self.stream.log("/world/entropy", rr.GridMap(
            data=data.tobytes(), format=fmt, cell_size=grid.resolution,
            translation=[grid.origin[0], grid.origin[1], Z_ENTROPY]))

    def log_exploration(self, explored: float, false_free: float) -> None:
        rr = self.rr
        self.stream.log("/metrics/explored/fraction", rr.Scalars(float(explored)))
        self.stream.log("/metrics/explored/false_free", rr.Scalars(float(false_free)))

    # ------------------------------------------------------------------ time-varying
    def set_time(self, seconds: float) -> None:
        self.stream.set_time(TIMELINE, duration=float(seconds))

    def log_cells(self, labels: np.ndarray, robot_ids=None) -> None:
        """The cell layer (skipped when it looks exactly like the last one logged)."""
        assert self._grid is not None, "log_map first"
        rr = self.rr
        grid = self._grid
        rgba = cells_rgba(labels, robot_ids)
        if self._last_cells is not None and np.array_equal(rgba, self._last_cells):
            return
        self._last_cells = rgba
        data, fmt = self._grid_map(grid, rgba, "RGBA")
        self.stream.log("/world/cells", rr.GridMap(
            data=data.tobytes(), format=fmt, cell_size=grid.resolution,
            translation=[grid.origin[0], grid.origin[1], Z_CELLS], opacity=CELL_OPACITY))

    def log_robots(self, robot_ids, positions: np.ndarray, radii) -> None:
        rr = self.rr
        P = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        ids = list(robot_ids)
        self.stream.log("/world/robots", rr.Points3D(
            np.column_stack([P, np.full(len(P), ROBOT_HEIGHT)]),
            radii=np.broadcast_to(np.asarray(radii, dtype=np.float32), (len(P),)),
            colors=robot_colors(ids), labels=[f"robot_{i}" for i in ids]))

    def log_goals(self, robot_ids, goals: np.ndarray) -> None:
        rr = self.rr
        G = np.asarray(goals, dtype=np.float64).reshape(-1, 2)
        ids = list(robot_ids)
        self.stream.log("/world/goals", rr.Points3D(
            np.column_stack([G, np.full(len(G), ROBOT_HEIGHT)]), radii=0.04,
            colors=robot_colors(ids)))

    def log_path(self, kind: str, robot_id: int, points: np.ndarray,
                 part: int | None = None) -> None:
        """``kind`` is ``trajectories`` or ``plans``; ``part`` k logs piece k of a path."""
        rr = self.rr
        P = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        strip = np.column_stack([P, np.full(len(P), ROBOT_HEIGHT)])
        path = f"/world/{kind}/robot_{robot_id}" + (f"/part_{part}" if part is not None else "")
        self.stream.log(path, rr.LineStrips3D(
            [strip], radii=0.015, colors=[robot_color(robot_id)]))

    def log_scan(self, robot_id: int, points: np.ndarray) -> None:
        rr = self.rr
        P = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        self.stream.log(f"/world/scans/robot_{robot_id}", rr.Points3D(
            np.column_stack([P, np.full(len(P), ROBOT_HEIGHT)]), radii=0.012,
            colors=[robot_color(robot_id)]))

    def log_trajectory(self, robot_id: int, tail: np.ndarray,
                       finished: Sequence[tuple[int, np.ndarray]] = ()) -> None:
        """A live trajectory: finished pieces (logged once each) and the growing tail."""
        for k, points in finished:
            self.log_path("trajectories", robot_id, points, part=k)
        self.log_path("trajectories", robot_id, tail)

    def log_polygon(self, robot_id: int, points: np.ndarray) -> None:
        """A cell outline ``(M, 2)`` [m], drawn closed."""
        P = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if len(P):
            P = np.vstack([P, P[:1]])
        self.stream.log(f"/world/cell_polygons/robot_{robot_id}", self.rr.LineStrips3D(
            [np.column_stack([P, np.full(len(P), ROBOT_HEIGHT)])], radii=0.01,
            colors=[robot_color(robot_id)]))

    def log_region(self, polygons: Sequence[np.ndarray]) -> None:
        """The region of interest: closed outlines ``(M, 2)`` [m] (none: the whole map)."""
        if not polygons:
            self.stream.log("/world/region", self.rr.Clear(recursive=False))
            return
        strips = []
        for poly in polygons:
            P = np.asarray(poly, dtype=np.float64).reshape(-1, 2)
            P = np.vstack([P, P[:1]])
            strips.append(np.column_stack([P, np.full(len(P), ROBOT_HEIGHT)]))
        self.stream.log("/world/region", self.rr.LineStrips3D(strips, radii=0.03,
                                                              colors=[[255, 255, 255]]))

    def log_values(self, entity: str, values: dict[str, float]) -> None:
        """Named values as one plot ``entity`` with a series per name (one entity, not one
        per value: every entity costs a chunk per batch). A name keeps its series; a value
        missing this time is NaN."""
        names = self._series.setdefault(entity, [])
        if any(n not in names for n in values):
            names.extend(n for n in values if n not in names)
            self.stream.log(entity, self.rr.SeriesLines(names=names), static=True)
        self.stream.log(entity, self.rr.Scalars(
            np.array([values.get(n, np.nan) for n in names], dtype=np.float64)))

    def clear(self, entity_path: str, recursive: bool = False) -> None:
        """Hide an entity from the current time on (a robot that left)."""
        self.stream.log(entity_path, self.rr.Clear(recursive=recursive))

    def log_metrics(self, H: float | None = None, masses: dict[int, float] | None = None,
                    ) -> None:
        rr = self.rr
        if H is not None and np.isfinite(H):
            self.stream.log("/metrics/H", rr.Scalars(float(H)))
        for rid, m in (masses or {}).items():
            self.stream.log(f"/metrics/mass/robot_{rid}", rr.Scalars(float(m)))

    def name_series(self, robot_ids) -> None:
        """Static series styling: names and robot colours for the mass plots."""
        rr = self.rr
        self.stream.log("/metrics/H", rr.SeriesLines(names="H", colors=[[230, 230, 230]]),
                        static=True)
        for rid in robot_ids:
            self.stream.log(f"/metrics/mass/robot_{rid}",
                            rr.SeriesLines(names=f"robot_{rid}", colors=[robot_color(rid)]),
                            static=True)


def index_recording(path: Path, timeout: float = 120.0) -> str | None:
    """Rewrite the finished recording ``path`` compacted and ending with rerun's chunk index
    (``rerun rrd optimize``; what ``rerun rrd verify`` and random access want) into a file
    beside it, then swap it in. A live recording is written without the index, which rerun would
    hold in memory for the whole run. Returns None, or why the file was left as it was (still a
    valid recording, without the index)."""
    exe = Path(sys.executable).with_name("rerun")
    found = str(exe) if exe.is_file() else shutil.which("rerun")
    if found is None:
        return f"left {path} without rerun's chunk index: no 'rerun' executable found"
    tmp = path.with_name(path.name + ".indexing")
    try:
        done = subprocess.run([found, "rrd", "optimize", str(path), "-o", str(tmp)],
                              capture_output=True, text=True, timeout=timeout)
    except (OSError, subprocess.TimeoutExpired) as exc:
        tmp.unlink(missing_ok=True)
        return f"left {path} without rerun's chunk index: {exc}"
    if done.returncode != 0:
        tmp.unlink(missing_ok=True)
        last = (done.stderr.strip().splitlines() or [f"exit code {done.returncode}"])[-1]
        return f"left {path} without rerun's chunk index: rerun rrd optimize: {last}"
    os.replace(tmp, path)
    return None
