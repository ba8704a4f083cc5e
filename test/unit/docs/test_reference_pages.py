"""The documentation site's reference shows everything the code declares: every node's
parameters, every command-line option, every strategy setting, every world and team file key
and every message - and its generated parts and results files render."""

from __future__ import annotations

import argparse
import dataclasses
import json
import re

import pytest
from conftest import REPO

from coverage_ros.docgen import pages, reference, results
from coverage_ros.nodes.reference import node_tables

DOCS = REPO / "docs"


def rendered(page: str) -> str:
    """A page's Markdown with its generated parts filled in, as the site shows it."""
    return pages.expand((DOCS / page).read_text(), page)


LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s#]+)(?:#[^)]*)?\)")


def test_every_relative_link_and_picture_of_the_pages_exists():
    """Links and pictures point at files of the site (mkdocs --strict checks the same, but
    only where its warnings are not silenced)."""
    broken = []
    for path in DOCS.rglob("*.md"):
        for target in LINK.findall(path.read_text()):
            if "://" not in target and not (path.parent / target).exists():
                broken.append(f"{path.relative_to(DOCS)}: {target}")
    assert broken == []


def test_every_marker_of_every_page_renders():
    markers = 0
    for path in DOCS.rglob("*.md"):
        text = path.read_text()
        markers += len(pages.MARKER.findall(text))
        assert pages.MARKER.search(pages.expand(text, str(path))) is None
    assert markers >= 10


@pytest.mark.parametrize("node", sorted(node_tables()))
def test_every_declared_parameter_is_on_its_node_page(node):
    page = rendered(f"reference/{node}.md")
    missing = [name for name in node_tables()[node] if f"| `{name}` |" not in page]
    assert missing == []


@pytest.mark.parametrize("program", sorted(reference.parsers()))
def test_every_command_line_option_is_on_its_page(program):
    page = rendered(f"reference/{program}.md")
    parser = reference.parsers()[program]()
    options = [s for a in parser._actions if not isinstance(a, argparse._HelpAction)
               for s in a.option_strings]
    assert options
    assert [o for o in options if not re.search(rf"`{re.escape(o)}\b", page)] == []


def test_the_reference_points_to_the_documentation_not_the_readme():
    """Parameter and option texts name documentation pages; README is a short overview."""
    texts = [t for table in node_tables().values() for _, t in table.values()]
    texts += [a.help for f in reference.parsers().values() for a in f()._actions if a.help]
    assert [t for t in texts if "README" in t] == []


def test_an_option_is_shown_with_its_value_default_and_expanded_help():
    ap = argparse.ArgumentParser(prog="x")
    ap.add_argument("--rate", type=float, default=2.0, help="[Hz] 50 %% of it | more")
    ap.add_argument("--pick", choices=("a", "b"), required=True)
    ap.add_argument("--flag", action="store_true", help="on")
    table = reference.cli_markdown(ap)
    assert r"| `--rate RATE` | `2.0` | [Hz] 50 % of it \| more |" in table
    assert "| `--pick {a,b}` | required |" in table
    assert "| `--flag` |  | on |" in table
    assert "--help" not in table


def test_every_strategy_setting_is_on_its_concept_page():
    from coverage_ros.core.strategies import EXPLORERS, STRATEGIES

    pages_of = {**{(n, False): f"concepts/{n}.md" for n in STRATEGIES},
                **{(n, True): "concepts/exploration.md" for n in EXPLORERS}}
    missing = []
    for (name, explores), page in pages_of.items():
        text = (DOCS / page).read_text()
        cls = (EXPLORERS if explores else STRATEGIES)[name]
        missing += [(name, f.name) for f in dataclasses.fields(cls.Params)
                    if f"`{f.name}`" not in text]
    assert missing == []


def test_every_world_and_team_file_key_is_on_the_files_page():
    from coverage_ros.core.world import density, loading, metric, robot, team

    text = (DOCS / "reference" / "files.md").read_text()
    keys = set(loading._WORLD_KEYS) | set(robot.ROBOT_KEYS) | set(robot.LIDAR_KEYS)
    keys |= set(team.MEMBER_KEYS) | set(density._KEYS) | set(density._COMPONENT_KEYS)
    for kind, names in loading._OBSTACLE_KEYS.items():
        keys |= {kind, *names}
    for kind, names in metric.CHART_KEYS.items():
        keys |= {kind, *names}
    for names in density._KEYS.values():
        keys |= set(names)
    assert sorted(k for k in keys if f"`{k}`" not in text) == []


def test_every_message_is_on_the_messages_page():
    page = rendered("reference/messages.md")
    names = [p.stem for p in reference.MESSAGES.glob("*.msg")]
    assert len(names) >= 4
    assert [n for n in names if f"### `coverage_msgs/msg/{n}`" not in page] == []


@pytest.mark.parametrize("path", sorted((DOCS / "results").glob("*.json")), ids=lambda p: p.stem)
def test_every_results_file_renders_with_where_it_came_from(path):
    text = results.results_markdown(path.stem)
    assert "No results yet" not in text
    assert "|---|" in text
    assert f"results/{path.stem}.json" in text
    assert "commit `" in text  # written with bench.results.provenance()


def test_results_rows_become_one_table_with_target_columns(tmp_path):
    data = {"machine": "Linux x86_64", "cores": 2, "python": "3.11", "date": "d",
            "commit": "abc1234", "command": "scripts/bench_x --quick",
            "rows": [{"setting": "16 robots", "rtf": 0.99, "target": "rtf >= 0.95", "met": True},
                     {"setting": "64 robots", "rtf": 0.871, "target": "rtf >= 0.95",
                      "met": False}]}
    (tmp_path / "x.json").write_text(json.dumps(data))
    text = results.results_markdown("x", tmp_path)
    assert "| setting | rtf | target | target met |" in text
    assert "| 16 robots | 0.99 | rtf >= 0.95 | yes |" in text
    assert "| 64 robots | 0.871 | rtf >= 0.95 | no |" in text
    assert "commit `abc1234`" in text and "`scripts/bench_x --quick`" in text
    assert "| d |" not in text and " d " not in text  # the date stays in the file


def test_a_missing_results_file_names_the_script_that_writes_it(tmp_path):
    assert "scripts/bench_team" in results.results_markdown("team", tmp_path)


def test_an_unknown_marker_fails_the_build():
    with pytest.raises(ValueError, match="unknown generated part"):
        pages.expand("<!-- generated: tables x -->", "page.md")
    with pytest.raises(ValueError, match="no parameter table"):
        pages.expand("<!-- generated: parameters nobody -->", "page.md")
