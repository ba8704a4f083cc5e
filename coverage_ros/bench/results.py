"""Where a benchmark's figures came from: the machine, the date, the commit and the command -
written into every results file (``docs/results/*.json``) next to the figures."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import time
from pathlib import Path

from coverage_ros.bench.environment import REPO


def provenance(argv: list[str] | None = None) -> dict[str, object]:
    """``{"machine", "cores", "python", "date", "commit", "command"}`` of this run."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO,
                                capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    script = Path(sys.argv[0]).name if argv is None else ""
    args = sys.argv[1:] if argv is None else argv
    return {"machine": f"{platform.system()} {platform.machine()}", "cores": os.cpu_count(),
            "python": platform.python_version(), "date": time.strftime("%Y-%m-%d"),
            "commit": commit or None, "command": " ".join([script, *args]).strip()}


#: Where the benchmark scripts write their results files; the documentation site's benchmark
#: pages are made from them (coverage_ros.docgen.results).
RESULTS_DIR = REPO / "docs" / "results"


def _under_test() -> bool:
    """A harness run by a test (pytest sets this variable) writes no results file: its short
    settings are not the benchmark's."""
    return "PYTEST_CURRENT_TEST" in os.environ


def write_results(name: str, figures: dict, argv: list[str] | None = None,
                  script: str | None = None) -> Path:
    """``docs/results/<name>.json``: ``figures`` with where they came from (replacing the
    file). ``script`` names the command as a user types it (default: the running one)."""
    import json

    prov = provenance(argv)
    if script is not None:
        prov["command"] = " ".join([script, *(sys.argv[1:] if argv is None else argv)])
    path = RESULTS_DIR / f"{name}.json"
    if _under_test():
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({**prov, **figures}, indent=1) + "\n")
    return path


def update_rows(name: str, rows: list[dict], key: tuple[str, ...],
                argv: list[str] | None = None, script: str | None = None,
                extra: dict | None = None) -> Path:
    """Put ``rows`` into ``docs/results/<name>.json``'s ``rows``, each replacing the row with
    the same values of ``key`` (one current result per setting), each row with the commit and
    command it came from; the file's own provenance is the newest run's, and ``extra``'s
    entries replace the file's others."""
    import json

    path = RESULTS_DIR / f"{name}.json"
    if _under_test():
        return path
    before = json.loads(path.read_text()) if path.exists() else {}
    old = before.get("rows", [])
    prov = provenance(argv)
    if script is not None:
        prov["command"] = " ".join([script, *(sys.argv[1:] if argv is None else argv)])
    new_keys = {tuple(r.get(k) for k in key) for r in rows}
    kept = [r for r in old if tuple(r.get(k) for k in key) not in new_keys]
    stamped = [{**r, "run": {k: prov[k] for k in ("date", "commit", "command")}} for r in rows]
    path.parent.mkdir(parents=True, exist_ok=True)
    others = {k: v for k, v in before.items() if k not in prov and k != "rows"}
    path.write_text(json.dumps({**prov, **others, **(extra or {}), "rows": kept + stamped},
                               indent=1) + "\n")
    return path
