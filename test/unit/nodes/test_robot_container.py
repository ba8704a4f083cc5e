"""Several robots per process: how the launcher groups robots and writes their parameters,
what the robots of one process share, robot_container's start-up errors, and the figures
bench_team reads back. The live team with shared processes runs in test_team_strategies
(lloyd: four robots in one process; the mixed team: two per process, each with its own body
from its section of the parameters file)."""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import REPO
from rosutil import domain_id, ros_env

from coverage_ros.bench.team import update_periods
from coverage_ros.cli.team.processes import ProcessStats
from coverage_ros.cli.team.robots import (
    default_robots_per_process,
    default_state_rate,
    default_update_load,
    plan_processes,
    robot_params,
    team_rates,
)
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError
from coverage_ros.nodes.robot_graph import SLOW_LOOKS, GraphLooks, state_topics
from coverage_ros.nodes.robot_shared import SharedInputs, grid_digest
from coverage_ros.nodes.runner import LastWords
from coverage_ros.nodes.update_worker import UpdatePool, UpdateTurns, UpdateWorker


def _params(ids, **extra):
    return {i: {"robot_id": i, "strategy": "lloyd", "robot_radius": 0.1 + 0.01 * i, **extra}
            for i in ids}


def test_robots_are_grouped_and_faulty_or_single_ones_run_alone(tmp_path):
    procs = plan_processes(_params(range(7)), 3, alone={4}, params_dir=tmp_path)
    assert [(p.name, p.ids) for p in procs] == [
        ("robots_0_2_5", (0, 2, 5)), ("robots_1_3_6", (1, 3, 6)), ("robot_4", (4,))]
    by_name = {p.name: p for p in procs}
    # A robot on its own is the plain robot_node, exactly as ros2 run would start it.
    cmd = by_name["robot_4"].cmd
    assert "robot_node" in " ".join(cmd[:cmd.index("--ros-args")])
    assert cmd[cmd.index("--ros-args"):] == [
        "--ros-args", "-r", "__ns:=/robot_4", "-p", "robot_id:=4", "-p", "strategy:=lloyd",
        "-p", "robot_radius:=0.14"]
    # A group: robot_container with its ids and one parameters file of per-node sections.
    cmd = by_name["robots_1_3_6"].cmd
    k = cmd.index("--ros-args")
    assert cmd[k - 3:k] == ["1", "3", "6"] and "robot_container" in cmd[k - 4]
    params_file = cmd[cmd.index("--params-file") + 1]
    assert Path(params_file) == by_name["robots_1_3_6"].params_file
    assert not any(tmp_path.iterdir())  # the plan writes nothing: the launcher does
    sections = yaml.safe_load(by_name["robots_1_3_6"].params_text)
    assert list(sections) == ["/robot_1/coverage_robot", "/robot_3/coverage_robot",
                              "/robot_6/coverage_robot"]
    assert sections["/robot_3/coverage_robot"]["ros__parameters"] == _params([3])[3]
    # The last group of one robot gets a robot_node, not a container of one.
    procs = plan_processes(_params(range(3)), 2, alone=set(), params_dir=tmp_path)
    assert sorted(p.name for p in procs) == ["robot_1", "robots_0-2_every_2"]
    procs = plan_processes(_params(range(4)), 4, alone=set(), params_dir=tmp_path)
    assert [(p.name, p.ids) for p in procs] == [("robots_0-3", (0, 1, 2, 3))]


def test_the_outer_ring_of_a_start_cluster_is_spread_over_the_processes(tmp_path):
    """Ids are dealt to the processes in turn: the launcher's start cluster puts the highest
    ids (the largest cells, the costliest updates) on its outside, and each of 4 processes of
    16 robots gets 4 of the 16 outermost instead of one process all of them."""
    procs = plan_processes(_params(range(64)), 16, alone=set(), params_dir=tmp_path)
    assert [p.name for p in procs] == [f"robots_{g}-{60 + g}_every_4" for g in range(4)]
    assert sorted(i for p in procs for i in p.ids) == list(range(64))
    assert all(len(p.ids) == 16 and sum(i >= 48 for i in p.ids) == 4 for p in procs)
    procs = plan_processes(_params(range(10)), 4, alone=set(), params_dir=tmp_path)
    assert [p.ids for p in procs] == [(0, 3, 6, 9), (1, 4, 7), (2, 5, 8)]


def test_default_robots_per_process_shares_processes_beyond_eight_robots_per_core():
    assert default_robots_per_process(16, cores=2) == 1
    assert default_robots_per_process(17, cores=2) == 5  # four processes
    assert default_robots_per_process(32, cores=2) == 8
    assert default_robots_per_process(64, cores=2) == 16
    assert default_robots_per_process(64, cores=8) == 1
    assert default_robots_per_process(65, cores=8) == 5


def test_robots_sharing_processes_get_the_larger_pooled_update_share():
    cores = os.cpu_count() or 1
    assert default_update_load(64) == pytest.approx(min(0.1, 0.15 * cores / 64))
    assert default_update_load(64, 16) == pytest.approx(min(0.1, 0.5 * cores / 64))
    assert default_update_load(2, 2) == 0.1  # at most a tenth of a core each


def test_robots_alone_in_a_big_team_publish_their_states_less_often():
    assert default_state_rate(16) == 2.5  # robot_node's default
    assert default_state_rate(32) == pytest.approx(40.0 / 31)  # 40 states a second each
    assert default_state_rate(64, 16) == 2.5  # a container parses each state once
    assert default_state_rate(1) == 2.5
    assert team_rates(32, 1, None, 2.0) == (pytest.approx(default_update_load(32)), 2.0)
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(ConfigError, match="--state-rate"):
            team_rates(32, 1, None, bad)
    with pytest.raises(ConfigError, match="--update-load"):
        team_rates(32, 1, 1.5, None)


def test_robot_params_are_read_as_rcl_reads_them_in_their_parameters_types():
    got = robot_params(["drive:=false", "comm_range:=4", "goal_tolerance:=0.25",
                        "strategy_params:={variant: nearest}", "map_topic:=''",
                        "bounds:=0,0,5,5", "world:=office", "robot_prefix:=[1, 2]"])
    assert got == {"drive": False, "comm_range": 4.0, "goal_tolerance": 0.25,
                   "strategy_params": "{variant: nearest}", "map_topic": "",
                   "bounds": "0,0,5,5", "world": "office", "robot_prefix": "[1, 2]"}
    assert isinstance(got["comm_range"], float)  # (a DOUBLE parameter refuses an integer)


def test_robots_of_a_process_share_worlds_and_domains_but_only_equal_ones():
    shared = SharedInputs()
    world = shared.world("office")
    assert shared.world("office") is world  # read once
    occ = world.grid.occupancy
    copy = GridMap(occ.copy(), world.grid.resolution, world.grid.origin)  # a second /map
    a = shared.domain(world.grid, 0.105, world.density, 8, False, world.metric)
    b = shared.domain(copy, 0.105, world.density, 8, False, world.metric)
    assert a is b and shared.domains_built == 1
    # Anything that changes the domain gives another one.
    assert shared.domain(copy, 0.16, world.density, 8, False, world.metric) is not a
    assert shared.domain(copy, 0.105, world.density, 16, False, world.metric) is not a
    moved = GridMap(occ.copy(), world.grid.resolution, (0.05, 0.0, 0.0))
    assert grid_digest(moved) != grid_digest(copy)
    changed = occ.copy()
    changed[5, 5] = 100 - changed[5, 5]
    assert grid_digest(GridMap(changed, world.grid.resolution, world.grid.origin)) != \
        grid_digest(copy)
    assert shared.domains_built == 3
    assert np.array_equal(a.free, b.free)


def test_robots_of_a_process_take_turns_with_their_updates():
    """Workers sharing the process's update slot never run two updates at once (the executor
    thread competes with at most one busy thread for the GIL), and each still runs its own."""
    shared = SharedInputs(update_slots=1)
    spans: list[tuple[int, float, float]] = []

    def work(k):
        def run(now):
            t0 = time.monotonic()
            time.sleep(0.05)
            spans.append((k, t0, time.monotonic()))
        return run

    workers = [UpdateWorker(work(k), load=1.0, slots=shared.update_slots) for k in range(3)]
    deadline = time.monotonic() + 30.0  # (rounds until each ran twice, however busy the host)
    while min(sum(k == j for k, _, _ in spans) for j in range(3)) < 2:
        assert time.monotonic() < deadline, spans
        for w in workers:
            w.request(0.0)
        time.sleep(0.2)
    for w in workers:
        w.close()
    assert len(spans) >= 6
    spans.sort(key=lambda s: s[1])
    assert all(a[2] <= b[1] for a, b in itertools.pairwise(spans)), spans
    assert SharedInputs().update_slots is None  # one robot per process: no turns


def test_a_freed_update_slot_goes_to_the_robot_that_waited_longest():
    """Calls waiting for the process's update slot go in the order of their workers' last
    starts, oldest first (not in the order they came)."""
    turns = UpdateTurns(1)
    turns.acquire()
    order = []

    def wait(last_start):
        turns.acquire(last_start)
        order.append(last_start)
        turns.release()

    threads = [threading.Thread(target=wait, args=(t,)) for t in (5.0, 1.0, 3.0, -np.inf)]
    for th in threads:
        th.start()
    deadline = time.monotonic() + 10.0
    while len(turns._waiting) < 4:  # (all four waiting, however late their threads started)
        assert time.monotonic() < deadline
        time.sleep(0.01)
    assert order == []
    turns.release()
    for th in threads:
        th.join(5.0)
    assert order == [-np.inf, 1.0, 3.0, 5.0]


def test_closing_the_workers_of_a_process_does_not_wait_for_the_queue():
    """Forty robots queued behind one long update: the process's exit waits for the running
    update at most, not for each queued robot's (they waited 5 s each)."""
    shared = SharedInputs(update_slots=1)
    release = threading.Event()
    ran: list[int] = []

    def work(k):
        def run(now):
            ran.append(k)
            release.wait(10.0)
        return run

    workers = [UpdateWorker(work(k), load=1.0, slots=shared.update_slots) for k in range(40)]
    for w in workers:
        w.request(0.0)
    deadline = time.monotonic() + 10.0
    while not ran:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    time.sleep(0.2)
    assert len(ran) == 1  # one runs, the others wait for its slot
    t0 = time.monotonic()
    for k, w in enumerate(workers):
        if k != ran[0]:
            w.close()
    assert time.monotonic() - t0 < 4.0  # (waiting for the queue: 5 s per queued robot)
    release.set()
    workers[ran[0]].close()
    assert ran == ran[:1] and sum(w.calls for w in workers) == 1  # the queued ones never ran


def test_the_robots_of_a_process_share_one_credit():
    """The pool's credit grows by the sum of the loads up to the largest burst (where it
    starts); a call may start once it is not negative."""
    pool = UpdatePool()
    pool.join(0.1, 0.5)
    pool.join(0.1, 1.0)
    assert (pool.load, pool.burst, pool.members) == (pytest.approx(0.2), 1.0, 2)
    t = time.monotonic() + 1.0
    assert pool.delay(t) == 0.0
    pool.spend(1.5, at=t)  # credit -0.5
    assert pool.delay(t) == pytest.approx(2.5)  # 0.5 / 0.2 per second
    assert pool.delay(t + 2.0) == pytest.approx(0.5)
    assert pool.delay(t + 2.6) == 0.0
    pool.spend(1.01, at=t + 100.0)  # refilled up to one burst only
    assert pool.delay(t + 100.0) == pytest.approx(0.05)


def test_pooled_workers_share_their_budget_and_take_turns():
    """Four workers of one process in one pool: three cheap ones asking every 2 ms and a
    costly one (ten times the CPU per call) asking every 50 ms. An asking worker queues for
    its turn and the credit instead of being refused, so the costly one updates about as often
    as the cheap ones (when the credit went to whoever asked first once it allowed, an earlier
    design: 3 calls against ~90 each); together they stay within the pool's burst + load x
    elapsed CPU seconds."""
    shared = SharedInputs(update_slots=1)

    def spin(ms):
        def run(now):
            end = time.thread_time() + ms / 1e3
            while time.thread_time() < end:
                pass
        return run

    load, burst = 0.05, 0.005
    workers = [UpdateWorker(spin(ms), load, burst=burst, slots=shared.update_slots,
                            pool=shared.update_pool) for ms in (2.0, 2.0, 2.0, 20.0)]
    t0 = asked = time.monotonic()
    try:
        while True:  # (until the cheap ones made 20 calls: load-independent)
            now = time.monotonic()
            if min(w.calls for w in workers[:3]) >= 20 or now - t0 > 30.0:
                break
            # the costly one every 50 ms of wall time (not every 25 turns of this loop, which
            # a busy host slows: then it asked 5 times while the cheap ones made 20 calls)
            costly = now - asked >= 0.05
            asked = now if costly else asked
            for w in workers if costly else workers[:3]:
                w.request(0.0)
            time.sleep(0.002)
    finally:
        for w in workers:
            w.close()
    calls = [w.calls for w in workers]
    assert calls[3] >= 10 and calls[3] >= 0.5 * min(calls[:3]), calls
    used = sum(sum(w.cpu_ms) for w in workers) / 1e3
    starts = max(w.starts[-1] for w in workers)
    assert used <= burst + 4 * load * (starts - t0) + 0.025, (used, calls)


def test_a_robot_that_hears_its_whole_team_looks_at_the_graph_seldom():
    looks = GraphLooks(team_size=4)
    assert all(looks.due(2) for _ in range(25))  # one of three missing: every period
    seldom = [looks.due(3) for _ in range(3 * SLOW_LOOKS)]
    assert sum(seldom) == 3
    assert looks.due(1)  # fewer known: every period again
    unknown = GraphLooks(team_size=0)
    assert all(unknown.due(50) for _ in range(25))  # team size unknown: always
    assert all(GraphLooks(4).due(-1) for _ in range(25))  # exploring: always


def test_state_topics_are_the_teams_own():
    names = [("/robot_3/coverage_state", ["coverage_msgs/msg/RobotState"]),
             ("/robot_12/coverage_state", ["coverage_msgs/msg/RobotState"]),
             ("/robot_4/coverage_state", ["std_msgs/msg/String"]),
             ("/robot_x/coverage_state", ["coverage_msgs/msg/RobotState"]),
             ("/other_5/coverage_state", ["coverage_msgs/msg/RobotState"]),
             ("/robot_6/cell", ["nav_msgs/msg/OccupancyGrid"])]
    assert list(state_topics(names, "robot_")) == [(3, "/robot_3/coverage_state"),
                                                   (12, "/robot_12/coverage_state")]


@pytest.mark.parametrize("args, message", [
    (["1", "1"], "ids must be distinct"),
    (["0", "1", "--ros-args", "-p", "strategy:=magic"], "robot 0: strategy: unknown strategy"),
    (["0", "1", "--ros-args", "-p", "control_rate:=0.0"],
     "robot 0: control_rate: must be a number > 0"),
    (["0", "1", "--ros-args", "-p", "control_rate:=fast"], "robot 0: "),
])
def test_container_start_up_errors_name_the_value(args, message):
    out = subprocess.run([sys.executable, "-m", "coverage_ros.nodes.robot_container", *args],
                         env=ros_env(domain_id(11)), capture_output=True, text=True, timeout=180,
                         cwd=REPO)
    assert out.returncode == 2
    err = out.stderr.strip().splitlines()  # the last line says it (argparse: after usage)
    assert err[-1].startswith("robot_container: error: ") and message in err[-1], out.stderr


class _Clock:
    """``time.monotonic`` for :mod:`coverage_ros.nodes.runner`, advanced by the waits alone: the
    budget's arithmetic checked exactly, however busy the machine."""

    def __init__(self) -> None:
        self.now = 1000.0

    def monotonic(self) -> float:
        return self.now


class _Publisher:
    """A publisher whose subscriber acknowledges after ``ack_s`` (None: never - it died); its
    wait passes on ``clock``."""

    def __init__(self, ack_s: float | None, clock: _Clock) -> None:
        self.ack_s, self.clock, self.sent, self.waits = ack_s, clock, [], []

    def publish(self, msg) -> None:
        self.sent.append(msg)

    def wait_for_all_acked(self, timeout) -> bool:
        wait = timeout.nanoseconds * 1e-9
        self.waits.append(wait)
        acked = self.ack_s is not None and self.ack_s <= wait
        self.clock.now += self.ack_s if acked else wait
        return acked


def test_the_robots_of_a_process_share_one_budget_for_their_last_commands(monkeypatch):
    """Each last command is sent and waited on until acknowledged; a subscriber that never
    acknowledges costs the process its budget once, not once per robot."""
    from coverage_ros.nodes import runner

    clock = _Clock()
    monkeypatch.setattr(runner, "time", clock)
    words = LastWords(budget=0.3)
    live = _Publisher(ack_s=0.01, clock=clock)
    assert words.publish(live, "stop 0") and live.sent == ["stop 0"]
    start = clock.now
    dead = [_Publisher(ack_s=None, clock=clock) for _ in range(4)]
    assert not any(words.publish(p, f"stop {k}") for k, p in enumerate(dead, 1))
    assert all(p.sent for p in dead)
    assert dead[0].waits[0] == pytest.approx(0.29) and [p.waits[0] for p in dead[1:]] == [0.0] * 3
    assert clock.now - start == pytest.approx(0.29)


def test_bench_team_reads_every_robots_update_periods_from_the_logs(tmp_path):
    """The benchmark's update periods come from the robots' own summary lines (the worker's
    format, whatever process the robot ran in)."""
    worker = UpdateWorker(lambda now: None, load=1.0)
    deadline = time.monotonic() + 30.0  # (a busy host may keep the worker's thread waiting)
    for k in range(4):
        while not worker.request(0.0) and time.monotonic() < deadline:
            time.sleep(0.005)
        while worker.calls <= k and time.monotonic() < deadline:
            time.sleep(0.005)
        time.sleep(0.05)
    worker.close()
    line = worker.summary()
    (tmp_path / "robots_2-3.log").write_text(
        f"[INFO] [1.0] [robot_2.coverage_robot]: {line}\n"
        f"[INFO] [1.0] [robot_container_2]: 8 states received\n"
        f"[INFO] [1.1] [robot_3.coverage_robot]: {line}\n")
    (tmp_path / "robot_0.log").write_text(f"[INFO] [1.0] [robot_0.coverage_robot]: {line}\n")
    periods = update_periods(tmp_path)
    assert sorted(periods) == [0, 2, 3]
    assert periods[2]["updates"] == 4
    assert 0.04 <= periods[3]["median_s"] <= periods[3]["longest_s"] < 30.0


def test_process_figures_per_robot_count_shared_processes_once():
    stats = ProcessStats.__new__(ProcessStats)  # no processes to sample: figures given
    stats.cpu = {"robots_0-7": [40.0, 60.0], "robot_8": [10.0], "world": [20.0]}
    stats.rss = {"robots_0-7": 360.0, "robot_8": 240.0, "world": 150.0}
    report = stats.report(robots=9)
    assert report["robot_processes"] == 2
    assert report["per_robot"] == {"cpu_percent": round(60.0 / 9, 2), "rss_mb": 66.7}
    assert report["robot_mean"] == {"cpu_percent": 30.0, "rss_mb_peak": 300.0}
