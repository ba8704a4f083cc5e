"""PNG pictures of a coverage plan: the map, an importance density or a belief's entropy under
each robot's cell in its colour, start and final positions, and trajectories. Image row 0 is
the top of the map (north up)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from coverage_ros.core.world.grid import GridMap
from coverage_ros.viz.colors import robot_colors

#: [px] target size of the longer image side.
TARGET_SIDE = 1000
FREE_RGB = (255, 255, 255)
OBSTACLE_RGB = (40, 40, 40)
UNKNOWN_RGB = (190, 190, 190)
CELL_ALPHA = 0.45  # how strongly a cell's colour tints the free space
UNDERLAY_RGB = (70, 110, 220)  # density / entropy tint, strongest where the underlay is 1
UNDERLAY_ALPHA = 0.6


def render_plan(grid: GridMap, labels: np.ndarray | None, trajectories: np.ndarray,
                path: str | Path, robot_ids=None, title: str | None = None,
                underlay: np.ndarray | None = None) -> Path:
    """Write the picture; ``labels (H, W)`` robot index per cell (-1 none), ``trajectories
    (T, n, 2)`` map-frame positions (first row: starts, last row: finals); ``underlay (H, W)``
    in [0, 1] - an importance density, or a belief's entropy - tints the free space under the
    cells."""
    from PIL import Image, ImageDraw

    H, W = grid.shape
    scale = max(1, int(TARGET_SIDE // max(H, W)))
    occ = grid.occupancy
    rgb = np.empty((H, W, 3), dtype=np.float64)
    rgb[:] = FREE_RGB
    rgb[occ < 0] = UNKNOWN_RGB
    rgb[occ >= 65] = OBSTACLE_RGB
    if underlay is not None:
        u = np.clip(np.asarray(underlay, dtype=np.float64), 0.0, 1.0)[..., None]
        free = occ < 65
        rgb[free] = ((1 - UNDERLAY_ALPHA * u) * rgb + UNDERLAY_ALPHA * u
                     * np.array(UNDERLAY_RGB))[free]
    n = trajectories.shape[1]
    ids = np.arange(n) if robot_ids is None else np.asarray(robot_ids)
    colors = robot_colors(ids).astype(np.float64)
    if labels is not None:
        lab = np.asarray(labels)
        own = lab >= 0
        rgb[own] = (1 - CELL_ALPHA) * rgb[own] + CELL_ALPHA * colors[lab[own]]
        # Darker outlines where neighbouring cells belong to different robots.
        edge = np.zeros_like(own)
        edge[:, 1:] |= own[:, 1:] & (lab[:, 1:] != lab[:, :-1])
        edge[1:, :] |= own[1:, :] & (lab[1:, :] != lab[:-1, :])
        rgb[edge] *= 0.55
    img = Image.fromarray(np.flipud(rgb).clip(0, 255).astype(np.uint8), "RGB")
    img = img.resize((W * scale, H * scale), Image.Resampling.NEAREST)
    draw = ImageDraw.Draw(img)

    def px(points: np.ndarray) -> np.ndarray:
        g = grid.world_to_grid(points) * scale
        return np.stack([g[..., 0], H * scale - g[..., 1]], axis=-1)

    r = max(4, int(0.25 / grid.resolution * scale / 2))  # markers of about a robot's size
    for i in range(n):
        c = tuple(int(v) for v in (colors[i] * 0.7))
        path_px = px(trajectories[:, i, :])
        if len(path_px) > 1:
            draw.line([tuple(p) for p in path_px], fill=c, width=max(2, scale // 2))
        x0, y0 = path_px[0]
        draw.ellipse([x0 - r, y0 - r, x0 + r, y0 + r], outline=c, width=2)
        x1, y1 = path_px[-1]
        draw.ellipse([x1 - r, y1 - r, x1 + r, y1 + r], fill=c, outline=(0, 0, 0))
        draw.text((x1 + r + 2, y1 - r), str(int(ids[i])), fill=(0, 0, 0))
    if title:
        draw.text((6, 6), title, fill=(0, 0, 0))
    path = Path(path)
    img.save(path)
    return path


def density_underlay(density: np.ndarray) -> np.ndarray | None:
    """An importance density scaled to [0, 1] for :func:`render_plan`, or None when it is
    constant over the cells where it is positive (a uniform density shows nothing)."""
    w = np.asarray(density, dtype=np.float64)
    pos = w[w > 0]
    if len(pos) == 0 or float(pos.max() - pos.min()) <= 1e-12 * float(pos.max()):
        return None
    return w / float(pos.max())


def padded_tracks(starts: np.ndarray, tracks: list[list[tuple[float, float]]]) -> np.ndarray:
    """``(T, n, 2)`` trajectories for :func:`render_plan` from each robot's start and its list
    of positions (of any length; a short one is held at its last point)."""
    rows = [[tuple(s[:2])] + list(t) for s, t in zip(starts, tracks, strict=True)]
    T = max(len(r) for r in rows)
    return np.array([[r[min(k, len(r) - 1)] for r in rows] for k in range(T)], dtype=np.float64)


def render_team(path, grid: GridMap, own: np.ndarray | None, alive: list[int],
                starts: np.ndarray, tracks: list[list[tuple[float, float]]],
                density: np.ndarray, title: str) -> Path:
    """A team run's picture (``coverage-team``'s ``summary.png``): ``own (H, W)`` cell labels
    indexing ``alive`` (robot ids), each robot's start and driven ``tracks``, the importance
    ``density`` under the cells."""
    labels = None
    if own is not None:
        labels = np.where(own >= 0, np.asarray(alive)[np.maximum(own, 0)], -1)
    return render_plan(grid, labels, padded_tracks(starts, tracks), path,
                       robot_ids=list(range(len(starts))), title=title,
                       underlay=density_underlay(density))
