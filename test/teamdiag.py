"""What a live team did at the end, for a failing assertion's message: a run that fails on a
team's H keeps only the test's output, so the message says where each robot stood, whether it
was lost, and its log's last decision and recovery lines."""

from __future__ import annotations

import json
from pathlib import Path

#: Robot log lines worth quoting (the end-of-run lines of the controller, and errors).
KEYS = ("last decision", "backed off", "gave way", "gave up", "Traceback", "Error")


def team_diagnosis(summary: dict, out: Path) -> str:
    """``summary`` (summary.json) and ``out`` (the team's output folder, with ``logs/``)."""
    m = summary["metrics"]
    lines = [f"metrics {json.dumps({k: v for k, v in m.items() if k != 'H_series'})}",
             f"H series {m.get('H_series')}"]
    for r in summary["robots"]:
        log = Path(out) / "logs" / f"robot_{r['id']}.log"
        tail = [ln.split("]: ", 1)[-1] for ln in log.read_text().splitlines()
                if any(k in ln for k in KEYS)][-4:] if log.exists() else ["no log"]
        lines.append(f"robot {r['id']} final {r['final']} lost_at {r.get('lost_at')} "
                     f"collisions {r['collisions']}: {tail}")
    return "\n".join(lines)
