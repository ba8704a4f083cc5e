"""Project exceptions.

Every message names where the problem is (file, field, parameter), the offending value, and what
was expected, so a user can fix the input without reading the code::

    office.yaml: obstacles[2].circle.radius: must be > 0 (got -0.5)
"""

from __future__ import annotations

from typing import Any


class CoverageError(Exception):
    """Base class of all coverage_ros errors."""


class ConfigError(CoverageError, ValueError):
    """A configuration value (file field, parameter, CLI option) is missing or invalid."""

    @classmethod
    def at(cls, where: str, problem: str, value: Any = ..., expected: str | None = None):
        """Build an error ``"<where>: <problem> (got <value>; expected <expected>)"``."""
        details = []
        if value is not ...:
            details.append(f"got {value!r}")
        if expected:
            details.append(f"expected {expected}")
        suffix = f" ({'; '.join(details)})" if details else ""
        return cls(f"{where}: {problem}{suffix}")


class MapError(ConfigError):
    """A map file (map_server YAML/image) cannot be read or is inconsistent."""


class WorldError(ConfigError):
    """A world description is invalid (unknown key, robot inside an obstacle, ...)."""
