"""The benchmark pages' tables, made from the results files the benchmark scripts write
(``docs/results/<name>.json``, each with :func:`coverage_ros.bench.results.provenance`).

A results file holds one current result per row. Where a file has ``rows`` (a list of
mappings) they become a table, one column per key, with ``target`` and ``met`` where the
benchmark sets targets; a file made of parts (``{"part": {...}, ...}``) becomes one table per
part; anything else becomes a table of its figures by key.
"""

from __future__ import annotations

import json
from pathlib import Path

from coverage_ros.docgen.reference import REPO, cell

RESULTS = REPO / "docs" / "results"
#: The script that writes each results file.
SCRIPTS = {"lockstep": "scripts/bench_lockstep", "team": "scripts/bench_team",
           "core": "scripts/bench_core", "explore": "scripts/bench_explore",
           "faults": "scripts/bench_faults", "papers": "scripts/bench_papers",
           "planner": "scripts/bench_planner", "closets": "scripts/bench_closets",
           "startup": "scripts/bench_startup"}
PROVENANCE = ("machine", "cores", "python", "date", "commit", "command")
#: Keys that say where a figure came from, not what it is: shown in the note under a table.
QUIET = set(PROVENANCE) | {"note", "settings"}
#: Results whose page shows their targets and rows only (every run's cases, restarts and
#: positions stay in the file).
ROWS_ONLY = {"closets"}
#: Longer lists of rows than this, beside a file's main rows, are left to the file.
MAX_ROWS = 12
#: Column headings that say more than the key: where a column is itself the target.
LABELS = {"identical": "identical beside CPU hogs (target: yes)", "met": "target met",
          "run": "commit"}


def value_text(value: object) -> str:
    """A figure as a table shows it."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.0f}" if abs(value) >= 1000 else f"{value:.4g}"
    if isinstance(value, list):
        if len(value) > 3 and all(type(v) is int for v in value) and \
                value == list(range(value[0], value[0] + len(value))):
            return f"{value[0]} to {value[-1]} ({len(value)})"  # (a sweep's seeds)
        return ", ".join(value_text(v) for v in value) if value else "-"
    if isinstance(value, dict):
        return "; ".join(f"{k} {value_text(v)}" for k, v in value.items())
    return str(value)


def provenance_note(data: dict, name: str) -> str:
    """Where the figures came from (commit, machine, command; the date stays in the file)."""
    parts = []
    if data.get("commit"):
        parts.append(f"commit `{data['commit']}`")
    if data.get("machine"):
        parts.append(f"{data['machine']}, {data.get('cores', '?')} cores, Python "
                     f"{data.get('python', '?')}")
    text = "Measured at " + ", ".join(parts) if parts else "Measured"
    if data.get("command"):
        text += f" by `{data['command']}`"
    text += f" ([{name}.json](results/{name}.json) has every figure and the date)."
    if data.get("settings"):
        text += f" Settings: {data['settings']}"
    if data.get("note"):
        text += f" {data['note']}"
    return text


#: The columns a page shows of a file's rows, where the file holds more than a page can
#: (the file keeps them all).
COLUMNS = {"team": ("robots", "world", "strategy", "robot_processes", "discovery", "executor",
                    "lockstep", "rtf", "rss_mb_per_robot", "cpu_percent_per_robot",
                    "update_period_worst_median_s", "H_reduction", "collisions", "target", "met",
                    "run")}


def rows_table(rows: list[dict], only: tuple[str, ...] | None = None) -> str:
    """Rows of mappings as a Markdown table, one column per key (in first-seen order), or the
    keys ``only`` names."""
    columns: list[str] = []
    for row in rows:
        columns += [k for k in row if k not in columns and k not in QUIET
                    and (only is None or k in only)]
    lines = ["| " + " | ".join(LABELS.get(c, c.replace("_", " ")) for c in columns) + " |",
             "|" + "---|" * len(columns)]
    for row in rows:
        lines.append("| " + " | ".join(cell(value_text(
            row[c].get("commit") if c == "run" and isinstance(row.get(c), dict) else row.get(c)))
            for c in columns) + " |")
    return "\n".join(lines)


def figures_table(data: dict) -> str:
    """A mapping's figures (nested keys joined with '.') as a two-column table."""
    flat: list[tuple[str, object]] = []

    def walk(prefix: str, value: object) -> None:
        if isinstance(value, dict):
            for k, v in value.items():
                if k not in QUIET:
                    walk(f"{prefix}.{k}" if prefix else k, v)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            flat.append((prefix, f"{len(value)} entries (see the file)"))
        else:
            flat.append((prefix, value))

    walk("", data)
    lines = ["| figure | value |", "|---|---|"]
    lines += [f"| {cell(k)} | {cell(value_text(v))} |" for k, v in flat]
    return "\n".join(lines)


def is_rows(value: object) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def part_markdown(data: dict, name: str) -> str:
    """One results mapping: its targets, its rows, then every other list of rows and mapping
    of figures under its key, and where they came from."""
    blocks = []
    if is_rows(data.get("targets")):
        blocks.append("**Targets**\n\n" + rows_table(data["targets"]))
    if is_rows(data.get("rows")):
        blocks.append(rows_table(data["rows"], COLUMNS.get(name)))
    scalars = {}
    for key, value in data.items():
        if key in ("rows", "targets") or key in QUIET or name in ROWS_ONLY:
            continue
        title = f"**{key.replace('_', ' ')}**\n\n"
        if is_rows(value) and len(value) > MAX_ROWS:
            blocks.append(title + f"{len(value)} rows: see the results file.")
        elif is_rows(value):
            blocks.append(title + rows_table(value))
        elif isinstance(value, dict):
            blocks.append(title + figures_table(value))
        else:
            scalars[key] = value
    if scalars:
        blocks.insert(0, figures_table(scalars))
    return "\n\n".join(blocks + [provenance_note(data, name)])


def results_markdown(name: str, folder: Path = RESULTS) -> str:
    """The tables of ``folder/<name>.json``, or a note naming the script that writes it."""
    path = folder / f"{name}.json"
    script = SCRIPTS.get(name, "its benchmark script")
    if not path.exists():
        return (f'!!! note "No results yet"\n    `{script}` writes `docs/results/{name}.json`; '
                "this table is made from it when the site is built.")
    data = json.loads(path.read_text())
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object")
    if name == "papers":
        return papers_markdown(data)
    if "rows" in data or any(k in data for k in PROVENANCE):
        return part_markdown(data, name)
    parts = [f"**{key.replace('_', ' ')}**\n\n{part_markdown(value, name)}"
             for key, value in data.items() if isinstance(value, dict)]
    return "\n\n".join(parts)


PAPER_COLUMNS = (("figure", "figure"), ("setting", "setting"), ("metric", "metric"),
                 ("paper_value", "paper's value (target)"), ("ours_median", "ours: median"),
                 ("ours_worst", "ours: worst"), ("seeds", "seeds"), ("verdict", "verdict"))
VERDICTS = ("as good or better", "within 20 %", "worse")
BETTER = {"lower": "lower is better", "higher": "higher is better", "close": "to match"}


def papers_markdown(data: dict) -> str:
    """``papers.json``: a count of verdicts per paper (its own methods' rows), then each
    paper's rows: the paper's value is the target, the verdict says whether it is met."""
    rows = data.get("rows", [])
    papers = list(dict.fromkeys(r["paper"] for r in rows))
    out = ["| paper | rows | " + " | ".join(VERDICTS) + " |", "|---|---|---|---|---|"]
    for paper in papers:
        own = [r for r in rows if r["paper"] == paper and not r.get("baseline")]
        counts = [sum(r["verdict"] == v for r in own) for v in VERDICTS]
        out.append(f"| {paper} | {len(own)} | " + " | ".join(map(str, counts)) + " |")
    runs = list(dict.fromkeys((r["run"].get("command"), r["run"].get("commit"))
                              for r in rows if isinstance(r.get("run"), dict)))
    out += ["", provenance_note(data, "papers")]
    if len(runs) > 1:
        out += ["", "The rows come from these runs: " + "; ".join(
            f"`{command}` (commit `{commit}`)" for command, commit in runs) + "."]
    for paper in papers:
        out += ["", f"### {paper}", "",
                "| " + " | ".join(label for _, label in PAPER_COLUMNS) + " |",
                "|" + "---|" * len(PAPER_COLUMNS)]
        for r in (r for r in rows if r["paper"] == paper):
            values = []
            for key, _ in PAPER_COLUMNS:
                text = value_text(r.get(key))
                if key == "metric" and r.get("better"):
                    text += f" ({BETTER.get(r['better'], r['better'])})"
                if key == "verdict" and r.get("baseline"):
                    text = f"baseline: {text}"
                if key == "setting" and r.get("redrawn") and "re-drawn" not in text:
                    text += " (re-drawn)"
                values.append(cell(text))
            out.append("| " + " | ".join(values) + " |")
    return "\n".join(out)
