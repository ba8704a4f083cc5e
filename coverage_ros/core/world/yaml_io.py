"""YAML input: files and parameter strings that must hold a mapping, with errors that name the
file (and line) or the parameter."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from coverage_ros.errors import ConfigError, MapError

#: libyaml's safe loader where PyYAML has it (the same documents, parsed about twice as fast)
SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def read_yaml_mapping(path: Path) -> dict[str, Any]:
    """Load a YAML file that must contain a mapping; errors name the file."""
    try:
        text = Path(path).read_text()
    except FileNotFoundError:
        raise MapError(f"{path}: file not found") from None
    except UnicodeDecodeError:
        raise MapError.at(str(path), "is not a text file", "binary data",
                          "a YAML file (for a map_server map: its .yaml, not the image)") from None
    except OSError as exc:
        raise MapError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        data = yaml.load(text, Loader=SAFE_LOADER)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark is not None else str(path)
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise MapError(f"{where}: malformed YAML ({problem})") from None
    if not isinstance(data, dict):
        raise MapError.at(str(path), "must contain a YAML mapping at the top level",
                          type(data).__name__, "key: value pairs")
    return data


def yaml_mapping(text: str, where: str) -> dict[str, Any]:
    """A YAML mapping typed as a parameter or option value (``""`` is an empty mapping)."""
    try:
        data = yaml.safe_load(text) if text else {}
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        at = f" at column {mark.column + 1}" if mark is not None else ""
        raise ConfigError.at(where, f"is not valid YAML ({problem}{at})", text) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError.at(where, "must be a YAML mapping", text)
    return data
