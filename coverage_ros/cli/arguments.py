"""Command-line helpers that coverage-team and coverage-plan share."""

from __future__ import annotations

#: Options whose values may begin with '-' (negative coordinates, as most map_server maps have).
COORDINATE_OPTIONS = ("--starts", "--region")


def attach_values(argv: list[str], options=COORDINATE_OPTIONS) -> list[str]:
    """``--starts -2.6,-9.1;...`` as ``--starts=-2.6,-9.1;...``: argparse takes a value that
    begins with '-' and is not a plain number for an unknown option."""
    out: list[str] = []
    it = iter(argv)
    for arg in it:
        if arg in options:
            value = next(it, None)
            out.append(arg if value is None else f"{arg}={value}")
        else:
            out.append(arg)
    return out
