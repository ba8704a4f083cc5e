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
