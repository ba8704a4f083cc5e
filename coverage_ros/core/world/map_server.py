"""Reading ROS map_server maps (YAML + PGM/PNG image) into a :class:`GridMap`.

The interpretation follows nav2_map_server's map_io:

* ``occ = (255 - v) / 255`` for an 8-bit pixel value ``v`` (``occ = v / 255`` when ``negate``);
  colour pixels are averaged over their colour channels first (in trinary mode the alpha channel
  is averaged in as well, as map_io does).
* ``mode: trinary`` (default): ``occ > occupied_thresh`` -> 100, ``occ < free_thresh`` -> 0,
  otherwise -1 (unknown).
* ``mode: scale``: like trinary, but values in between become
  ``round(100 * (occ - free_thresh) / (occupied_thresh - free_thresh))``; a transparent pixel
  (alpha < 255) is unknown.
* ``mode: raw``: the pixel value itself (0..100), 255 (or anything above 100) is unknown.
* Image row 0 is the top of the map, so it becomes the *last* grid row (grid row 0 is at the
  origin).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from coverage_ros.core.world.grid import FREE, OCCUPIED, UNKNOWN, GridMap
from coverage_ros.core.world.yaml_io import read_yaml_mapping
from coverage_ros.errors import MapError

MAP_YAML_KEYS = {"image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh",
                 "mode"}
MAP_MODES = ("trinary", "scale", "raw")


def is_map_server_yaml(data: dict[str, Any]) -> bool:
    """Whether a parsed YAML mapping looks like a map_server map (has ``image``)."""
    return "image" in data


def _number(path: Path, data: dict[str, Any], key: str, default: float | None = None) -> float:
    if key not in data:
        if default is None:
            raise MapError.at(f"{path}: {key}", "required field is missing",
                              expected="a number")
        return default
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise MapError.at(f"{path}: {key}", "must be a finite number", value)
    return float(value)


def load_map_yaml(path: str | Path) -> GridMap:
    """Load a map_server map from its YAML file (the image path is relative to the YAML)."""
    path = Path(path)
    data = read_yaml_mapping(path)
    return grid_from_map_yaml(path, data)


def grid_from_map_yaml(path: Path, data: dict[str, Any]) -> GridMap:
    """Build the grid from an already parsed map_server YAML mapping read from ``path``."""
    unknown = sorted(set(data) - MAP_YAML_KEYS)
    if unknown:
        raise MapError.at(f"{path}: {unknown[0]}", "unknown key in map_server YAML",
                          expected=f"one of {sorted(MAP_YAML_KEYS)}")
    image = data.get("image")
    if not isinstance(image, str) or not image:
        raise MapError.at(f"{path}: image", "required field must name the map image", image)
    resolution = _number(path, data, "resolution")
    if resolution <= 0:
        raise MapError.at(f"{path}: resolution", "must be > 0 metres per cell", resolution)
    origin = data.get("origin")
    if (not isinstance(origin, list | tuple) or len(origin) != 3
            or not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                       for v in origin)):
        raise MapError.at(f"{path}: origin", "must be a list of three numbers [x, y, yaw]", origin)
    negate = data.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise MapError.at(f"{path}: negate", "must be 0 or 1", negate)
    occupied_thresh = _number(path, data, "occupied_thresh", 0.65)
    free_thresh = _number(path, data, "free_thresh", 0.25)
    if not 0.0 <= free_thresh < occupied_thresh <= 1.0:
        raise MapError.at(f"{path}: free_thresh/occupied_thresh",
                          "need 0 <= free_thresh < occupied_thresh <= 1",
                          (free_thresh, occupied_thresh))
    mode = data.get("mode", "trinary")
    if mode not in MAP_MODES:
        raise MapError.at(f"{path}: mode", "unknown map mode", mode, f"one of {MAP_MODES}")
    image_path = Path(image) if Path(image).is_absolute() else path.parent / image
    pixels, alpha = read_map_image(image_path, where=f"{path}: image")
    occupancy = pixels_to_occupancy(pixels, alpha, bool(negate), occupied_thresh, free_thresh,
                                    mode)
    x, y, yaw = (float(v) for v in origin)
    return GridMap(np.flipud(occupancy), resolution, (x, y, yaw))


def read_map_image(image_path: Path, where: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Read a map image as values in 0..255 (row 0 = top) and an optional ``(H, W)`` alpha
    channel in 0..255 (255 = opaque).

    The values are ``(H, W)``, or ``(H, W, C)`` with the colour channels' mean repeated ``C``
    times when the image has an alpha channel (C = 3 for RGBA, 1 for LA).
    """
    from PIL import Image, UnidentifiedImageError  # local: only map loading needs Pillow

    if not image_path.exists():
        raise MapError.at(where, "map image not found", str(image_path))
    try:
        with Image.open(image_path) as img:
            img.load()
            mode = img.mode
            arr = np.asarray(img)
    except (UnidentifiedImageError, OSError) as exc:
        raise MapError.at(where, f"cannot read map image ({exc})", str(image_path)) from None
    alpha = None
    if mode in ("I;16", "I;16B", "I;16L", "I"):
        # 16-bit PGM: scale to the 8-bit range map_io works in.
        arr = arr.astype(np.float64) * (255.0 / max(float(arr.max()), 255.0))
    elif arr.ndim == 3:
        if mode in ("RGBA", "LA", "PA"):
            alpha = arr[..., -1].astype(np.float64)
            arr = arr[..., :-1]
        arr = arr.astype(np.float64)
        if arr.shape[2] == 1:
            arr = arr[..., 0]
        else:
            arr = arr.mean(axis=2)
        if alpha is not None:
            # Keep the colour-channel count so trinary mode can average alpha in like map_io.
            arr = np.stack([arr] * (3 if mode == "RGBA" else 1), axis=-1)
    elif mode == "P":
        raise MapError.at(where, "palette images are not supported; save as greyscale",
                          str(image_path))
    else:
        arr = arr.astype(np.float64)
        if mode == "1":
            arr = arr * 255.0
    return arr, alpha


def pixels_to_occupancy(pixels: np.ndarray, alpha: np.ndarray | None, negate: bool,
                        occupied_thresh: float, free_thresh: float, mode: str) -> np.ndarray:
    """Apply map_server's pixel interpretation; returns ``(H, W) int8`` in image row order."""
    channels = pixels[..., None] if pixels.ndim == 2 else pixels
    if alpha is not None and mode == "trinary":
        shade = np.concatenate([channels, alpha[..., None]], axis=-1).mean(axis=-1)
    else:
        shade = channels.mean(axis=-1)
    pixels = shade
    if mode == "raw":
        raw = np.rint(pixels).astype(np.int16)
        out = np.where(raw > 100, UNKNOWN, raw)
        return out.astype(np.int8)
    occ = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
    out = np.full(pixels.shape, UNKNOWN, dtype=np.int16)
    out[occ > occupied_thresh] = OCCUPIED
    out[occ < free_thresh] = FREE
    if mode == "scale":
        between = (occ >= free_thresh) & (occ <= occupied_thresh)
        scaled = np.rint(100.0 * (occ - free_thresh) / (occupied_thresh - free_thresh))
        out[between] = scaled[between].astype(np.int16)
        if alpha is not None:
            out[alpha < 255] = UNKNOWN
    return out.astype(np.int8)


def write_map_yaml(grid: GridMap, yaml_path: str | Path, image_name: str | None = None) -> Path:
    """Save a grid as a map_server map (trinary PGM + YAML); returns the YAML path."""
    from PIL import Image

    yaml_path = Path(yaml_path)
    image_name = image_name or yaml_path.with_suffix(".pgm").name
    occ = np.flipud(grid.occupancy)
    img = np.full(occ.shape, 205, dtype=np.uint8)  # unknown: map_saver's grey
    img[(occ >= 0) & (occ < 65)] = 254
    img[occ >= 65] = 0
    Image.fromarray(img, mode="L").save(yaml_path.parent / image_name)
    yaml_path.write_text(yaml.safe_dump({
        "image": image_name, "mode": "trinary", "resolution": grid.resolution,
        # free_thresh 0.196 (ROS map_saver's value) keeps the grey 205 of unknown cells unknown.
        "origin": list(grid.origin), "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196,
    }, sort_keys=False))
    return yaml_path
