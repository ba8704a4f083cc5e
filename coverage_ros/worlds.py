"""Finding world files: a path, or the name of a world shipped in ``config/worlds``."""

from __future__ import annotations

import contextlib
from pathlib import Path

from coverage_ros.errors import WorldError

PACKAGE = "coverage_ros"
SOURCE_WORLDS = Path(__file__).resolve().parents[1] / "config" / "worlds"


def shipped_world_dirs() -> list[Path]:
    """Folders holding the shipped worlds: the installed share dir (ament index), then the
    source tree."""
    dirs = []
    try:
        from ament_index_python.packages import (
            PackageNotFoundError,
            get_package_share_directory,
        )

        # Not installed, or AMENT_PREFIX_PATH unset: the source tree only.
        with contextlib.suppress(PackageNotFoundError, OSError):
            dirs.append(Path(get_package_share_directory(PACKAGE)) / "config" / "worlds")
    except ImportError:  # no ament index: running from the source tree only
        pass
    dirs.append(SOURCE_WORLDS)
    return [d for d in dirs if d.is_dir()]


def resolve_world_path(value: str, where: str = "world") -> Path:
    """``value`` as a file path if it looks like one (has a ``/`` or ends in ``.yaml``/``.yml``),
    else the shipped world of that name. Raises :class:`WorldError` for unknown names; a missing
    file is reported by the loader, which names the path."""
    if not isinstance(value, str) or not value.strip():
        raise WorldError.at(where, "must be a world name or a path to a YAML file", value)
    if "/" in value or value.endswith((".yaml", ".yml")):
        return Path(value).expanduser()
    names: set[str] = set()
    for folder in shipped_world_dirs():
        candidate = folder / f"{value}.yaml"
        if candidate.is_file():
            return candidate
        names.update(p.stem for p in folder.glob("*.yaml"))
    raise WorldError.at(where, "no shipped world of that name", value,
                        f"one of {sorted(names)} or a path to a .yaml file")
