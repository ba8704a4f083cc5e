"""Reference tables made from the code: the command-line tools' options (their argparse
parsers) and the messages (``interfaces/coverage_msgs/msg/*.msg``)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
MESSAGES = REPO / "interfaces" / "coverage_msgs" / "msg"


def parsers() -> dict[str, Callable[[], argparse.ArgumentParser]]:
    """Each command-line tool's parser factory, by program name."""
    from coverage_ros.cli.plan import build_parser as plan
    from coverage_ros.cli.team.options import build_parser as team
    from coverage_ros.cli.teleop import build_parser as teleop

    return {"coverage-team": team, "coverage-plan": plan, "coverage-teleop": teleop}


def cell(text: str) -> str:
    """``text`` for one cell of a Markdown table (one line, pipes escaped)."""
    return " ".join(text.split()).replace("|", r"\|")


def option_usage(action: argparse.Action) -> str:
    """``--robots N``, ``--strategy {a,b}``, ``--record``: how an option is written."""
    names = ", ".join(action.option_strings) or action.dest
    if action.nargs == 0:
        return names
    if action.metavar is not None:
        value = str(action.metavar)
    elif action.choices is not None:
        value = "{" + ",".join(str(c) for c in action.choices) + "}"
    else:
        value = action.dest.upper()
    if action.nargs == "?":
        value = f"[{value}]"
    return f"{names} {value}"


def option_default(action: argparse.Action) -> str:
    """The default as the table shows it: blank where there is none to show."""
    default = action.default
    if action.required:
        return "required"
    if default is None or default is False or default == [] or default == argparse.SUPPRESS:
        return ""
    if default == "":
        return "`''`"
    return f"`{default}`"


def cli_markdown(parser: argparse.ArgumentParser) -> str:
    """A Markdown table of every option of ``parser`` (its own ``--help`` left out): how it is
    written, its default, its help text with argparse's ``%`` expansions done."""
    formatter = parser._get_formatter()
    rows = ["| option | default | meaning |", "|---|---|---|"]
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        text = formatter._expand_help(action) if action.help else ""
        rows.append(f"| `{cell(option_usage(action))}` | {option_default(action)} | "
                    f"{cell(text)} |")
    return "\n".join(rows)


def message_markdown(path: Path) -> str:
    """One message: its name as a heading and its definition, comments included."""
    return (f"### `coverage_msgs/msg/{path.stem}`\n\n"
            f"```\n{path.read_text().rstrip()}\n```")


def messages_markdown(folder: Path = MESSAGES) -> str:
    """Every message of ``folder``, by name."""
    return "\n\n".join(message_markdown(p) for p in sorted(folder.glob("*.msg")))
