"""Every command the tutorials tell a user to type runs: each is taken word for word from its
page (the test fails when the page no longer holds it), run in lock-step at a short duration
with its output in a temporary folder, and must end with exit code 0 and its files written."""

from __future__ import annotations

import json
import shlex
import subprocess

import pytest
from conftest import REPO, entry_point
from rosutil import domain_id

pytestmark = [pytest.mark.slow, pytest.mark.lockstep]

DOCS = REPO / "docs"
#: (page, command as the page writes it, sim seconds to run it for instead). Teams run in
#: lock-step whatever the page says, so the run is short and reproducible; plans stop after
#: :data:`PLAN_ITERATIONS` (their results are checked in test_plan_cli.py and the benchmarks).
COMMANDS = [
    ("tutorials/known-map.md", "coverage-team --world office --robots 6 --duration 90 --lockstep",
     6),
    ("tutorials/known-map.md",
     "coverage-team --world field --robots 8 --strategy lloyd --duration 90 --record", 5),
    ("tutorials/known-map.md",
     "coverage-team --world l_shape --robots 4 --duration 70 --kill 1@25 --lockstep", 0),
    ("tutorials/known-map.md",
     "coverage-team --world l_shape --robots 4 --duration 70 --restart 1@25", 0),
    ("tutorials/known-map.md",
     "coverage-plan --map office --robots 6 --json out/plan.json --png out/plan.png", 0),
    ("tutorials/known-map.md", "coverage-plan --map gaussians --robots 8 --strategy lloyd "
     "--solver accelerated --json out/lloyd.json", 0),
    ("tutorials/known-map.md", "coverage-team --world ward --robots 8 --duration 900 "
     "--until-settled 60 --lockstep", 6),
    ("tutorials/explore.md", "coverage-team --explore --world office --robots 4 --until-explored "
     "0.95 --duration 600 --lockstep", 8),
    ("tutorials/explore.md", "coverage-team --explore --world office --robots 4 --strategy "
     "frontier --duration 240", 6),
    ("tutorials/mixed-team.md",
     "coverage-team --team config/teams/burgers_and_waffles.yaml --world office --lockstep", 6),
    ("tutorials/mixed-team.md", "coverage-team --team config/teams/sensor_footprints.yaml "
     "--world office --duration 120 --lockstep", 6),
    ("tutorials/region.md", 'coverage-team --world office --robots 4 --region '
     '"8.2,0.2;11.8,0.2;11.8,3.2;8.2,3.2" --lockstep', 6),
    ("tutorials/reproduce-a-paper.md", "coverage-plan --map /tmp/sphere.yaml --robots 4 --png "
     "out/sphere.png --json out/sphere.json", 0),
    ("concepts/bvc.md", "coverage-team --world office --robots 4 --strategy bvc --map-free "
     "--duration 90 --lockstep", 6),
    ("concepts/acvt.md",
     "coverage-team --world targets --robots 10 --strategy acvt --duration 240 --lockstep", 4),
]

#: A plan's updates at most here (the office's six robots take 84 updates and 48 s of CPU to
#: converge, most of it spent looking for a better configuration).
PLAN_ITERATIONS = 30


def runnable(command: str, tmp_path, seconds: float, k: int) -> list[str]:
    """The command with its outputs in ``tmp_path``, quiet; for a plan, at most
    :data:`PLAN_ITERATIONS` updates; for a team, lock-step, a domain of this test's and
    ``seconds`` of sim time (at least enough for a --kill / --restart)."""
    words = shlex.split(command.replace("out/", f"{tmp_path}/").replace(
        "/tmp/sphere.yaml", f"{tmp_path}/sphere.yaml"))
    words[0] = entry_point(words[0])
    if "coverage-plan" in command:
        return words + ["--quiet", "--max-iterations", str(PLAN_ITERATIONS)]
    if "@" in command:  # a robot killed or restarted at 25 s: run past it
        seconds = 30
    return words + ["--lockstep", "--quiet", "--no-markers", "--duration", str(seconds),
                    "--out", str(tmp_path / "team"), "--domain-id", str(domain_id(k))]


@pytest.mark.parametrize("k, page, command, seconds",
                         [(k, *c) for k, c in enumerate(COMMANDS)],
                         ids=[f"{c[0].split('/')[-1][:-3]}-{k}" for k, c in enumerate(COMMANDS)])
def test_a_tutorial_command_runs(k, page, command, seconds, tmp_path):
    text = (DOCS / page).read_text()
    assert command in " ".join(text.replace("\\\n", " ").split()), f"{page} no longer says it"
    if "sphere.yaml" in command:  # the page writes it with a heredoc first
        (tmp_path / "sphere.yaml").write_text(
            "name: sphere\nchart: {type: sphere, cells_per_pi: 64, cap: 6}\n")
    proc = subprocess.run(runnable(command, tmp_path, seconds, k), capture_output=True,
                          text=True, timeout=420, cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-3000:]
    if command.startswith("coverage-team"):
        summary = json.loads((tmp_path / "team" / "summary.json").read_text())
        assert summary["interrupted"] is False
        assert (tmp_path / "team" / "summary.png").stat().st_size > 1000
        if "--record" in command:
            assert (tmp_path / "team" / "recording.rrd").stat().st_size > 1000
        if "--explore" in command:
            assert "exploration" in summary
    else:
        written = [w for w in shlex.split(command) if w.endswith((".json", ".png"))]
        assert all((tmp_path / w.split("/")[-1]).stat().st_size > 0 for w in written)
