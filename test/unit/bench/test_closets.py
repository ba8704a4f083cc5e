"""scripts/bench_closets' summary: the README's table is the results file's figures."""

from __future__ import annotations

import json
import shutil
import sys
from collections import Counter
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from coverage_ros.bench.closet_maps import (
    HOSTEL_ABOVE,
    HOSTEL_BELOW,
    MAPS,
    RESOLUTION,
    ROBOTS,
    coarse_world,
    drawn_plan,
    entry,
    entry_map,
    floor_plan,
    hostel,
    hostel_plan,
    known_map,
    twin_plan,
)
from coverage_ros.bench.closets_live import within_at, world_file
from coverage_ros.bench.closets_results import (
    README,
    README_BEGIN,
    README_END,
    RESULTS,
    best_and_ratios,
    map_names,
    summary_table,
    update_readme,
)
from coverage_ros.bench.environment import SHARED_MAPS
from coverage_ros.bench.results import provenance
from coverage_ros.core.world import load_world, parse_world
from coverage_ros.core.world.placement import largest_free_region


def _data(ratios_before, ratios_after):
    def cases(ratios):
        return {"maps": {"ward": {"cases": [{"ratio": r} for r in ratios]}}}

    return {"runs": {"before": cases(ratios_before), "after": cases(ratios_after)},
            "best": {"ward": {"H": 498.6, "restarts": 10}}}


def test_summary_gives_every_start_before_and_after():
    table = summary_table(_data([2.228, 1.316, 2.061], [1.005, 1.004, 1.0]))
    assert table.splitlines()[2] == "| ward | 498.6 (10) | 2.228 / 1.316 / 2.061 " \
        "| 1.005 / 1.004 / 1.000 |"


def test_the_best_known_is_the_lowest_h_of_any_run_on_the_same_problem():
    """Restarts, offline cases and live cases alike (how a configuration was found does not
    change its H); a case with another team size or raster is another problem."""
    problem = {"robots": 8, "resolution": 0.1}
    data = {"restarts": {"ward": {"H": [500.0, 510.0], "settings": {
                **problem, "max_iterations": 300, "restart_seed": 1000}}},
            "runs": {
                "after": {"maps": {"ward": {"settings": {**problem, "max_iterations": 300},
                                            "cases": [{"H": 505.0}]}}},
                "live": {"maps": {"ward": {"settings": {**problem, "live": True,
                                                        "duration": 900.0},
                                           "cases": [{"H": 495.0}, {"H": 515.0}]}}},
                "twice": {"maps": {"ward": {"settings": {**problem, "robots": 16},
                                            "cases": [{"H": 250.0}]}}}}}
    data["runs"]["live"]["provenance"] = {"commit": "abc1234"}
    best_and_ratios(data)
    assert data["best"]["ward"] == {"H": 495.0, "restarts": 2, "escape_restarts": 0,
                                    "problem": problem,
                                    "found": {"label": "live", "seed": None,
                                              "commit": "abc1234"}}
    assert data["runs"]["after"]["maps"]["ward"]["cases"][0]["ratio"] == 505.0 / 495.0
    live = data["runs"]["live"]["maps"]["ward"]
    assert live["worst_ratio"] == 515.0 / 495.0 and live["met"]
    # the live row run again, ending higher: the configuration found before still counts
    live["cases"] = [{"H": 502.0}]
    best_and_ratios(data)
    assert data["best"]["ward"]["H"] == 495.0 and live["worst_ratio"] == 502.0 / 495.0
    # ... on the same problem only
    data["restarts"]["ward"]["settings"]["resolution"] = 0.05
    data["runs"]["after"]["maps"]["ward"]["settings"]["resolution"] = 0.05
    best_and_ratios(data)
    assert data["best"]["ward"]["H"] == 500.0
    assert data["best"]["ward"]["found"] == {"restart": 0}


def test_restarts_with_escape_count_towards_the_best_known_and_show_in_the_table():
    problem = {"robots": 8, "resolution": 0.1}
    settings = {**problem, "max_iterations": 300}
    data = {"restarts": {"ward": {"H": [500.0, 510.0],
                                  "settings": {**settings, "restart_seed": 1000}}},
            "runs": {label: {"maps": {"ward": {"settings": settings, "cases": [
                {"H": h} for h in hs]}}} for label, hs in (("before", (900.0, 800.0)),
                                                            ("after", (502.0, 505.0)))}}
    best_and_ratios(data)
    assert data["best"]["ward"]["H"] == 500.0 and data["best"]["ward"]["escape_restarts"] == 0
    assert summary_table(data).splitlines()[2].startswith("| ward | 500 (2) | ")
    data["restarts"]["ward"]["escape_H"] = [501.0, 498.0]
    data["restarts"]["ward"]["escape_provenance"] = {"commit": "abc1234"}  # (the code run)
    best_and_ratios(data)
    assert data["best"]["ward"]["H"] == 498.0
    assert data["best"]["ward"]["found"] == {"restart with escape": 1, "commit": "abc1234"}
    assert data["runs"]["after"]["maps"]["ward"]["worst_ratio"] == 505.0 / 498.0
    assert summary_table(data).splitlines()[2] == \
        f"| ward | 498 (2 + 2) | {900 / 498:.3f} / {800 / 498:.3f} | " \
        f"{502 / 498:.3f} / {505 / 498:.3f} |"


def test_restarts_on_record_are_kept_and_extended_not_run_again(monkeypatch):
    """Plain restarts run again (more asked for) keep the restarts with escape on record; more
    of those asked for run only the new ones, from the starts a run from scratch would draw."""
    import coverage_ros.bench.closets as closets

    calls = []

    def run_team(domain, world, starts, params, max_iterations):
        calls.append((np.array(starts), dict(params)))
        return {"H": float(np.round(starts, 3).sum()), "iterations": 1, "relocations": 0,
                "seconds": 0.0, "H_start": 0.0}

    monkeypatch.setattr(closets, "run_team", run_team)

    key = entry("plan-1", 3)  # (a team of 3: its own restarts, beside the 8 robots' ones)

    def bench(restarts: int, escape: int, stored: dict) -> dict:
        args = SimpleNamespace(robots=3, resolution=0.1, max_iterations=5, restart_seed=7,
                               restarts=restarts, escape_restarts=escape, seeds=0, params={})
        result = closets.bench_map("plan-1", args, stored, lambda msg: None)
        stored[key] = result["restarts"]
        return result["restarts"]

    eight = {"settings": {"robots": 8}, "H": [1.0]}
    stored: dict = {"plan-1": eight}
    first = bench(1, 3, stored)
    assert stored["plan-1"] is eight and key == "plan-1, 3 robots"
    assert len(first["H"]) == 1 and len(first["escape_H"]) == 3
    assert first["escape_provenance"]["commit"] == provenance()["commit"]  # (the code run)
    scratch = [c for c in calls if c[1] == {}]
    calls.clear()
    again = bench(2, 0, stored)  # (plain restarts again: the escape ones kept)
    assert len(again["H"]) == 2 and again["escape_H"] == first["escape_H"]
    assert again["escape_provenance"] == first["escape_provenance"]
    assert all(c[1] != {} for c in calls)
    calls.clear()
    stored[key]["escape_H"] = first["escape_H"][:2]
    more = bench(2, 3, stored)  # (one more with escape: the third of the stream)
    assert len(calls) == 1 and np.array_equal(calls[0][0], scratch[2][0])
    assert more["escape_H"] == first["escape_H"]


def test_update_replaces_only_the_marked_table(tmp_path):
    path = tmp_path / "README.md"
    path.write_text(f"intro\n{README_BEGIN}\nold\n{README_END}\nrest\n")
    assert update_readme(_data([2.0], [1.0]), path)
    text = path.read_text()
    assert text.startswith(f"intro\n{README_BEGIN}\n| map |") and text.endswith(
        f"| ward | 498.6 (10) | 2.000 | 1.000 |\n{README_END}\nrest\n")
    path.write_text("no markers\n")
    assert not update_readme(_data([2.0], [1.0]), path)
    assert path.read_text() == "no markers\n"


def test_readme_table_is_the_results_file():
    text = README.read_text()
    block = text.split(README_BEGIN, 1)[1].split(README_END, 1)[0].strip()
    assert block == summary_table(json.loads(RESULTS.read_text()))


def test_every_hostel_room_opens_onto_the_corridor():
    """The drawn floor plan: one free region a robot can drive holds the corridor and the
    middle of each of the ten rooms."""
    world = hostel()
    region = largest_free_region(world.grid, world.robot_spec(0).radius)
    centres = [(0.5 * (x0 + x1), y) for rooms, y in ((HOSTEL_BELOW, 2.0), (HOSTEL_ABOVE, 7.1))
               for x0, x1 in _spans(rooms)] + [(8.0, 4.6)]
    for centre in centres:
        row, col = world.grid.world_to_cell(np.array(centre))
        assert region[row, col], centre


def test_drawn_plans_are_one_region_a_robot_can_drive_with_rooms_behind_doors():
    """Every drawn plan: the seed alone gives it; all its free space a robot keeps clear of
    the walls in is one region (every room and closet reachable through its door); and it has
    dead ends - rooms off the corridor, and closets inside rooms on some plans."""
    from scipy import ndimage

    from coverage_ros.core.world.placement import CLUSTER_WALL_MARGIN

    closets = 0
    for seed in range(12):
        plan = drawn_plan(seed)
        assert plan == drawn_plan(seed) == floor_plan(f"plan-{seed}")
        world = parse_world(plan)
        assert yaml.safe_load(yaml.safe_dump(plan)) == plan  # (a world file the launcher reads)
        free = world.grid.inflated_free_mask(world.robot_spec(0).radius + CLUSTER_WALL_MARGIN)
        _, regions = ndimage.label(free, structure=np.ones((3, 3)))
        assert regions == 1, seed
        # walls across the corridor part rooms; walls along it are the corridor's two sides
        # (door gaps between pieces) and the fronts of closets
        x0, y0, x1, y1 = plan["bounds"]
        along = 1 if x1 - x0 > y1 - y0 else 0  # (the axis across the corridor)
        walls = [(o["from"], o["to"]) for o in plan["obstacles"]]
        assert sum(1 for a, b in walls if a[along] != b[along]) >= 4, seed
        lines = Counter(a[along] for a, b in walls if a[along] == b[along])
        sides = {v for v, _ in lines.most_common(2)}
        closets += len(set(lines) - sides)
    assert closets > 0


def test_twin_plans_are_one_region_with_two_corridors_and_rooms_back_to_back():
    """Every two-corridor plan: the seed alone gives it; all its free space a robot keeps
    clear of the walls in is one region; and the middle rooms' shared back wall runs the
    building's length, broken once by the cross corridor, whose sides meet it there."""
    from scipy import ndimage

    from coverage_ros.core.world.placement import CLUSTER_WALL_MARGIN

    for seed in range(12):
        plan = twin_plan(seed)
        assert plan == twin_plan(seed) == floor_plan(f"twin-{seed}")
        world = parse_world(plan)
        assert yaml.safe_load(yaml.safe_dump(plan)) == plan
        free = world.grid.inflated_free_mask(world.robot_spec(0).radius + CLUSTER_WALL_MARGIN)
        _, regions = ndimage.label(free, structure=np.ones((3, 3)))
        assert regions == 1, seed
        walls = [(o["from"], o["to"]) for o in plan["obstacles"]]
        middles = []
        for axis in (0, 1):  # (walls across axis: constant coordinate 1 - axis)
            span = plan["bounds"][2 + axis]
            lines: dict[float, list[tuple[float, float]]] = {}
            for a, b in walls:
                if a[1 - axis] == b[1 - axis]:
                    lines.setdefault(a[1 - axis], []).append(tuple(sorted((a[axis], b[axis]))))
            for at, pieces in lines.items():
                pieces.sort()
                if len(pieces) == 2 and pieces[0][0] == 0.0 and pieces[1][1] == span:
                    gap = (pieces[0][1], pieces[1][0])
                    sides = [(a, b) for a, b in walls if a[axis] == b[axis]
                             and a[axis] in gap and min(a[1 - axis], b[1 - axis]) < at
                             < max(a[1 - axis], b[1 - axis])]
                    middles.append((1.2 <= gap[1] - gap[0] <= 2.0, len(sides)))
        assert middles == [(True, 2)], (seed, middles)


def test_floor_plans_and_map_names():
    assert floor_plan("hostel") == hostel_plan()
    assert floor_plan("ward") is None and floor_plan("plan-x") is None
    assert known_map("ward") and known_map("plan-12") and not known_map("plan-") \
        and not known_map("nowhere")
    assert known_map("twin-3") and floor_plan("twin-3") == twin_plan(3) != drawn_plan(3)
    data = {"best": {"twin-4": {}, "plan-10": {}, "ward": {}, "twin-12": {}, "plan-2": {}}}
    assert map_names(data)[-4:] == ["plan-2", "plan-10", "twin-4", "twin-12"]


def test_a_team_of_another_size_is_an_entry_of_its_own():
    """The benchmark's own team keeps the map's name; another size gets its own key, parsed
    back, and its rows follow every row of the 8 robots, by size, each in map order."""
    assert entry("office", ROBOTS) == "office" and entry_map("office") == ("office", ROBOTS)
    for name, robots in (("office", 12), ("plan-7", 4), ("twin-2", 16)):
        assert entry_map(entry(name, robots)) == (name, robots)
    data = {"best": {entry("plan-3", 12): {}, "plan-3": {}, entry("office", 4): {},
                     entry("office", 12): {}, "ward": {}, entry("twin-1", 12): {},
                     entry("nowhere", 12): {}}}
    names = map_names(data)
    assert names[:len(MAPS)] == list(MAPS) and names[len(MAPS):] == [
        "plan-3", "office, 4 robots", "office, 12 robots", "plan-3, 12 robots",
        "twin-1, 12 robots"]


def _spans(rooms):
    x = 0.0
    for width, _ in rooms:
        yield x, x + width
        x += width


def test_live_column_shows_each_start_and_maps_not_run():
    data = _data([2.0, 1.5], [1.0, 1.01])
    data["best"]["office"] = {"H": 178.9, "restarts": 10}
    for label, ratios in (("before", [2.5]), ("after", [1.0])):
        data["runs"][label]["maps"]["office"] = {"cases": [{"ratio": r} for r in ratios]}
    data["runs"]["live"] = {"settings": {"duration": 300.0}, "maps": {
        "ward": {"settings": {"duration": 400.0},
                 "cases": [{"ratio": 1.02}, {"ratio": 1.104}]}}}
    lines = summary_table(data).splitlines()
    assert lines[0].endswith("| after | live: the launcher's team, lock-step (sim time) |")
    assert lines[1] == "|---|---|---|---|---|"
    assert lines[2] == "| office | 178.9 (10) | 2.500 | 1.000 | - |"
    assert lines[3] == ("| ward | 498.6 (10) | 2.000 / 1.500 | 1.000 / 1.010 "
                        "| 1.020 / 1.104 (400 s) |")
    # Runs until settled: each case's end, the duration for one that never settled.
    data["runs"]["live"]["maps"]["ward"] = {
        "settings": {"duration": 900.0, "until_settled": 60.0},
        "cases": [{"ratio": 1.02, "settled_at": 412.5}, {"ratio": 1.104, "settled_at": None}]}
    assert summary_table(data).splitlines()[3].endswith(
        "| 1.020 / 1.104 (ended at 412 / 900 unsettled s, once settled for 60 s) |")


def test_within_at_is_the_start_of_the_last_stay_within_five_percent():
    series = [[0.0, 300.0], [10.0, 104.0], [20.0, 106.0], [30.0, 104.9], [40.0, 101.0]]
    assert within_at(series, 100.0) == 30.0
    assert within_at(series[:3], 100.0) is None
    assert within_at([], 100.0) is None


def test_live_worlds_are_the_offline_rasters(tmp_path):
    """What the launcher loads for a live run is the world the offline cases score on: a floor
    plan at the benchmark's resolution, a map_server map in blocks of its cells."""
    for name in ("ward", "hostel", "tb3_sandbox"):
        path, world = world_file(name, RESOLUTION, tmp_path)
        loaded = load_world(str(path))
        assert loaded.grid.resolution == RESOLUTION, name
        assert np.array_equal(loaded.grid.occupancy, world.grid.occupancy), name
    base = load_world(str(SHARED_MAPS / "tb3_sandbox.yaml"))
    assert np.array_equal(load_world(str(tmp_path / "tb3_sandbox.yaml")).grid.occupancy,
                          coarse_world(base, RESOLUTION).grid.occupancy)


def test_a_wrong_option_is_refused_in_one_line_before_anything_runs(tmp_path, capsys):
    from coverage_ros.bench.closets import main

    out = tmp_path / "closets.json"
    assert main(["--label", "x", "--maps", "office,nope", "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--maps" in err[0] and "nope" in err[0], err
    assert main(["--label", "x", "--live", "--duration", "0", "--json", str(out)]) == 2
    assert "--duration" in capsys.readouterr().err
    assert main(["--label", "x", "--keep", str(tmp_path), "--json", str(out)]) == 2
    assert "--keep" in capsys.readouterr().err
    assert main(["--label", "x", "--live", "--record", "--json", str(out)]) == 2
    assert "--record" in capsys.readouterr().err
    assert main(["--label", "x", "--escape-restarts", "-1", "--json", str(out)]) == 2
    assert "--escape-restarts" in capsys.readouterr().err
    assert main(["--label", "x", "--live", "--escape-restarts", "2", "--json", str(out)]) == 2
    assert "--escape-restarts" in capsys.readouterr().err
    assert main(["--label", "x", "--robots", "0", "--json", str(out)]) == 2
    assert "--robots" in capsys.readouterr().err
    assert not out.exists()


def test_a_failed_live_run_keeps_its_folder_and_names_it(tmp_path, monkeypatch):
    """The benchmark's temporary folder goes when it ends; a failed run's world file and logs
    stay where the error says."""
    from coverage_ros.bench import closets_live

    fail = "import pathlib, sys; a = sys.argv; o = pathlib.Path(a[a.index('--out') + 1]); " \
        "(o / 'logs').mkdir(parents=True); (o / 'logs' / 'world.log').write_text('stuck'); " \
        "sys.exit('no tick')"
    monkeypatch.setattr(closets_live, "TEAM", [sys.executable, "-c", fail])
    args = SimpleNamespace(robots=2, resolution=RESOLUTION, until_settled=0, params=None,
                           keep=None)
    folder = tmp_path / "ward" / "seed-1"
    with pytest.raises(RuntimeError, match="no tick") as failed:
        closets_live.run_case("ward", 1, args, folder, 10.0)
    kept = Path(str(failed.value).split(" are in ")[1].split(":\n")[0])
    try:
        assert not kept.is_relative_to(tmp_path)
        assert (kept / "ward-1" / "logs" / "world.log").read_text() == "stuck"
        assert (kept / "ward.yaml").is_file()
    finally:
        shutil.rmtree(kept.parent)
