"""The markers a documentation page holds and what each becomes.

``<!-- generated: parameters robot_node -->``   the node's parameter table (its ``PARAMETERS``)
``<!-- generated: cli coverage-team -->``        the command's options (its argparse parser)
``<!-- generated: messages -->``                 every ``coverage_msgs`` message definition
``<!-- generated: results lockstep -->``         the tables of ``docs/results/lockstep.json``

An unknown kind or name raises :class:`ValueError` (the strict site build then fails); a results
file that does not exist yet becomes a note saying which script writes it.
"""

from __future__ import annotations

import re
from collections.abc import Callable

MARKER = re.compile(r"<!-- generated: ([a-z]+)(?: ([A-Za-z0-9_.-]+))? -->")


def _parameters(node: str | None) -> str:
    from coverage_ros.nodes.parameters import markdown_table
    from coverage_ros.nodes.reference import node_tables

    tables = node_tables()
    if node not in tables:
        raise ValueError(f"no parameter table for node {node!r} (nodes: {', '.join(tables)})")
    return markdown_table(tables[node])


def _cli(program: str | None) -> str:
    from coverage_ros.docgen.reference import cli_markdown, parsers

    known = parsers()
    if program not in known:
        raise ValueError(f"no parser for {program!r} (commands: {', '.join(known)})")
    return cli_markdown(known[program]())


def _messages(_: str | None) -> str:
    from coverage_ros.docgen.reference import messages_markdown

    return messages_markdown()


def _results(name: str | None) -> str:
    from coverage_ros.docgen.results import results_markdown

    if not name:
        raise ValueError("results needs the name of a file in docs/results/")
    return results_markdown(name)


GENERATORS: dict[str, Callable[[str | None], str]] = {
    "parameters": _parameters, "cli": _cli, "messages": _messages, "results": _results}


def expand(text: str, where: str = "page") -> str:
    """``text`` with every marker replaced by what it stands for."""

    def one(match: re.Match[str]) -> str:
        kind, name = match.group(1), match.group(2)
        if kind not in GENERATORS:
            raise ValueError(f"{where}: unknown generated part {kind!r} "
                             f"(known: {', '.join(GENERATORS)})")
        try:
            return GENERATORS[kind](name)
        except ValueError as err:
            raise ValueError(f"{where}: {err}") from err

    return MARKER.sub(one, text)
