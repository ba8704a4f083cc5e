"""The launcher when things go wrong on a live team: a domain someone else is on is not picked,
interrupts at any moment - during start-up too - leave no process behind and end with one line
and a summary, never a traceback; a second simulation, a restarted robot, taken ports."""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import time

import psutil
import pytest
from conftest import NO_ESCAPE, entry_point
from rosutil import NodeProcess, domain_id, ros_env
from teamdiag import team_diagnosis

from coverage_ros.cli.team.domains import foreign_participants


def team_cmd(*args: str) -> list[str]:
    """coverage-team with ``args``."""
    return [entry_point("coverage-team"), *args]


@pytest.fixture(autouse=True)
def own_lock_dir(tmp_path, monkeypatch):
    """Locks of this test's runs only (the machine's real runs keep theirs)."""
    monkeypatch.setenv("COVERAGE_ROS_LOCK_DIR", str(tmp_path / "locks"))


def test_a_domain_with_someone_else_on_it_is_not_picked():
    busy = domain_id(24)
    with NodeProcess.world_node(busy, "world:=l_shape", "num_robots:=1"):
        deadline = time.monotonic() + 20
        seen: list[str] = []
        while not seen and time.monotonic() < deadline:
            seen = foreign_participants(busy, 1.0)
        assert seen, "no node seen on a domain with a world node"
    assert foreign_participants(domain_id(25), 0.5) == []


def _is_fork_server(p: psutil.Process) -> bool:
    with contextlib.suppress(psutil.Error):
        return "coverage_ros.nodes.preloaded" in p.cmdline() and p.name() == "python"
    return False


def _described(pids: list[int]) -> list[str]:
    """Each process as ``top`` names it, with its state and parent (for a failure's message)."""
    out = []
    for pid in pids:
        try:
            p = psutil.Process(pid)
            out.append(f"{pid} {p.name()} ({p.status()}, parent {p.ppid()})")
        except psutil.Error as exc:
            out.append(f"{pid} ({type(exc).__name__})")
    return out


def _log_tails(logs, pids: list[int], lines: int = 8) -> str:
    """The last ``lines`` of each process's log in ``logs``, found by the name ``top`` shows
    (for a failure's message: where a process left behind was)."""
    out = []
    for pid in pids:
        with contextlib.suppress(psutil.Error, OSError):
            name = psutil.Process(pid).name()
            for log in sorted(logs.glob(f"{name}*.log")):
                tail = log.read_text(errors="replace").splitlines()[-lines:]
                out.append("\n".join([f"--- {log.name}", *tail]))
    return "\n".join(out)


def _watched_until(launcher: int, when: float) -> dict[int, psutil.Process]:
    """The launcher's processes by PID, every one seen until ``when`` [s] after its first node
    process (its own start-up takes seconds; the fork server comes first, the node processes
    once it has loaded their code)."""
    seen: dict[int, psutil.Process] = {}
    started, limit = None, time.monotonic() + 60.0
    while started is None or time.monotonic() < started + when:
        assert time.monotonic() < limit, "the launcher started no process within 60 s"
        for p in _children(launcher):
            seen.setdefault(p.pid, p)
        if started is None and any(not _is_fork_server(p) for p in seen.values()):
            started = time.monotonic()
        time.sleep(0.2)
    return seen


def _children(pid: int) -> list[psutil.Process]:
    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


# during start-up, in the middle of the run (the team's own start-up takes over 12 s on a slow
# host with the unit tests beside it)
@pytest.mark.parametrize("when", [2.0, 30.0])
def test_an_interrupt_at_any_moment_leaves_nothing_behind(tmp_path, when):
    out = tmp_path / "team"
    team = subprocess.Popen(team_cmd("--world", "l_shape", "--robots", "4", "--duration", "120",
                                     "--out", str(out), "--quiet",
                                     "--domain-id", str(domain_id(27 if when < 10 else 28))),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=ros_env(domain_id(27)), start_new_session=True)
    seen = _watched_until(team.pid, when)
    team.send_signal(signal.SIGINT)
    t0 = time.monotonic()
    _, err = team.communicate(timeout=30)
    gone = time.monotonic() - t0
    alive = [p.pid for p in seen.values() if p.is_running() and p.status() != "zombie"]
    try:
        assert not alive, f"left behind: {_described(alive)}"
        # The stop escalates in 10 s at most (SIGINT, 4 s, SIGTERM, 3 s, SIGKILL, 3 s); the rest
        # is the summary, written by a process that a loaded machine may keep waiting.
        assert gone <= 20.0, gone
        assert team.returncode == 130, err
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
        assert "interrupted" in err
        summary = json.loads((out / "summary.json").read_text())
        assert summary["interrupted"] is True
        if when > 10:
            assert summary["sim_time"] > 0 and len(summary["robots"]) == 4
    finally:
        for pid in alive:
            os.killpg(pid, signal.SIGKILL)


#: Ctrl-C while rclpy builds a received message in Python: the launcher's handlers, a message
#: whose constructor receives the signal, and what comes out of the spin.
_INTERRUPT_IN_A_MESSAGE = """
import os, signal
import rclpy
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import String
from coverage_ros.cli.interrupts import Interrupts

rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
stop = Interrupts()
node = rclpy.create_node("interrupt_probe")
node.create_subscription(String, "probe", lambda msg: None, 10)
publisher = node.create_publisher(String, "probe", 10)
armed = []
build = String.__init__

def build_then_signal(self, *args, **kwargs):
    build(self, *args, **kwargs)
    if armed:
        os.kill(os.getpid(), signal.SIGINT)

String.__init__ = build_then_signal
try:
    for _ in range(100):
        publisher.publish(String(data="x"))
        armed.append(True)
        rclpy.spin_once(node, timeout_sec=0.1)
        armed.clear()
    print("no message arrived")
except (KeyboardInterrupt, RuntimeError) as exc:
    print(type(exc).__name__, "interrupt" if stop.caused(exc) else "failure", exc)
"""


def test_an_interrupt_while_rclpy_builds_a_message_counts_as_an_interrupt():
    """The signal's KeyboardInterrupt raised inside rclpy's C++ comes out of the spin as
    pybind11's conversion error: the launcher takes it for the interrupt, not a failure."""
    probe = subprocess.run([sys.executable, "-c", _INTERRUPT_IN_A_MESSAGE], capture_output=True,
                           text=True, timeout=60, env=ros_env(domain_id(28)))
    assert probe.returncode == 0, probe.stderr
    assert probe.stdout.startswith("RuntimeError interrupt Unable to convert"), probe.stdout


@pytest.mark.parametrize("when", [3.0, 10.0])  # [s] after its first node process
def test_a_launcher_killed_during_a_big_start_up_leaves_nothing_behind(tmp_path, when):
    """SIGKILL gives the launcher no say: its children go because the kernel tells them
    (PR_SET_PDEATHSIG), and a process half-way through creating its fifty robots stops at
    once instead of finishing them first."""
    team = subprocess.Popen(team_cmd("--world", "l_shape", "--robots", "200",
                                     "--duration", "120", "--out", str(tmp_path / "team"),
                                     "--quiet", "--no-markers", "--domain-id",
                                     str(domain_id(29))),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env=ros_env(domain_id(29)), start_new_session=True)
    seen = _watched_until(team.pid, when)
    team.kill()
    team.wait()
    deadline = time.monotonic() + 30.0  # (four processes of fifty robots unwinding, loaded)
    alive = list(seen)
    while alive and time.monotonic() < deadline:
        time.sleep(0.2)
        alive = [pid for pid, p in seen.items() if p.is_running() and p.status() != "zombie"]
    try:
        assert len(seen) >= 4, seen  # the world and the robots' processes
        assert not alive, (f"left behind 30 s after the launcher died: {_described(alive)}\n"
                           f"{_log_tails(tmp_path / 'team' / 'logs', alive)}")
    finally:
        for pid in alive:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(pid, signal.SIGKILL)


@pytest.mark.slow
def test_serve_web_takes_free_ports_and_shows_the_team_in_a_browser(tmp_path):
    """Another run holds the default ports (9090, 9876): the web viewer still comes up, on
    ports the kernel gave, and its address is printed on the console even with --quiet. A
    headless Chromium opens that address and the viewer in it holds the team: the map, cells,
    robots, paths and the H and mass plots (read back from the recording the viewer saves)."""
    import socket
    import urllib.request

    from browser import HeadlessViewer
    from rerun.chunk import RrdReader
    from selenium.common.exceptions import TimeoutException as SeleniumTimeout

    held = []
    for port in (9090, 9876):
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        with contextlib.suppress(OSError):  # already taken by something else: as good
            sock.bind(("127.0.0.1", port))
            sock.listen(1)
        held.append(sock)
    out = tmp_path / "team"
    proc = subprocess.Popen(
        [entry_point("coverage-team"), "--quiet", "--world", "empty",
         "--robots", "2", "--duration", "600", "--serve-web", "--no-markers", "--out", str(out),
         "--domain-id", str(domain_id(6))],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    want = {"/world/map", "/world/cells", "/world/robots", "/world/goals", "/metrics/H"}
    want |= {f"/{kind}/robot_{i}" for kind in ("world/trajectories", "world/plans",
                                               "metrics/mass") for i in range(2)}
    try:
        line = proc.stderr.readline()
        m = re.match(r"coverage-team: web viewer at (http://127\.0\.0\.1:(\d+)/\?url=\S+)", line)
        assert m, line
        assert int(m.group(2)) not in (9090, 9876)
        page = None
        answer_by = time.monotonic() + 120.0  # the viewer comes up with the bridge
        while page is None and time.monotonic() < answer_by:
            with contextlib.suppress(OSError):
                page = urllib.request.urlopen(m.group(1), timeout=2).read()
                break
            time.sleep(0.5)
        assert page, "the web viewer never answered"
        with HeadlessViewer(m.group(1)) as viewer:
            viewer.wait_started()
            seen: set[str] = set()
            deadline = time.monotonic() + 180.0  # s: a busy 2-core machine's browser is slow
            attempt = 0
            while time.monotonic() < deadline:
                attempt += 1
                # A viewer asked before the first data arrived holds no recording yet: it
                # refuses to save, or saves an empty file; a busy page may not answer in time.
                try:
                    rrd = viewer.save_recording(tmp_path / f"browser-{attempt}.rrd")
                except (AssertionError, SeleniumTimeout) as exc:
                    if isinstance(exc, AssertionError) and "No active recording" not in str(exc):
                        raise
                    time.sleep(1.0)
                    continue
                with contextlib.suppress(ValueError):
                    seen = set(RrdReader(rrd).store().schema().entity_paths())
                if want <= seen:
                    break
                time.sleep(1.0)
            viewer.screenshot(tmp_path / "browser.png")
            assert viewer.panic() is None, viewer.panic()
        assert want <= seen, f"the browser's viewer lacks {sorted(want - seen)} (has {seen})"
        # (a run long enough for any machine's browser to connect, ended by Ctrl-C once seen)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        for sock in held:
            sock.close()
    assert proc.returncode == 130, err[-3000:]
    assert "already in use" not in (out / "logs" / "bridge.log").read_text()


@pytest.mark.slow
def test_a_second_simulation_on_the_domain_stops_the_team_with_one_line(tmp_path):
    """Someone starts another world node on the team's domain mid-run: the launcher and the
    robots notice the second /clock (or the clock going back), say so and stop, instead of
    running on a mixture of two simulations."""
    domain = domain_id(7)
    out = tmp_path / "team"
    proc = subprocess.Popen(
        [entry_point("coverage-team"), "--world", "empty", "--robots", "2",
         "--duration", "120", "--no-markers", "--out", str(out), "--domain-id", str(domain)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        lines = []
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            line = proc.stderr.readline()
            lines.append(line)
            if "team ready" in line or not line:
                break
        assert any("team ready" in line for line in lines), "".join(lines)
        with NodeProcess.world_node(domain, "world:=empty", "num_robots:=1"):
            _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 1, err[-2000:]
    last = err.strip().splitlines()[-1]
    assert last.startswith("coverage-team: error: ") and "/clock" in last, err[-2000:]


@pytest.mark.slow
@pytest.mark.lockstep
def test_a_restarted_robot_rejoins_and_the_team_reconverges(tmp_path):
    """Robot 1's process is killed mid-run and started again with the same id (its body stays,
    as a robot whose software crashed): it rejoins, nobody counts it lost, and the team ends
    spread out. In lock-step the world holds the tick until the new process answers, so it
    answers every tick from the restart to the end (at real time with memory sampled:
    test_soak.py)."""
    out = tmp_path / "team"
    proc = subprocess.run(
        [entry_point("coverage-team"), "--quiet", "--world", "empty", "--lockstep",
         "--robots", "3", "--duration", "45", "--seed", "2", "--restart", "1@15",
         "--no-markers", *NO_ESCAPE,
         "--out", str(out), "--domain-id", str(domain_id(29))],
        capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    robots = {r["id"]: r for r in summary["robots"]}
    assert robots[1]["restarted_at"] == [pytest.approx(15.0, abs=0.2)]
    assert all("lost_at" not in r for r in robots.values())
    log = (out / "logs" / "robot_1.log").read_text()
    assert log.count("robot 1: strategy geodesic") == 2  # two processes, one log
    # Only the second process lived to say how many ticks it answered: each of the 30 s
    # (300 ticks of 0.1 s) after the restart.
    answered = [int(n) for n in re.findall(r"answered (\d+) robot ticks", log)]
    assert len(answered) == 1 and answered[0] >= 295, answered
    m = summary["metrics"]
    assert m["H"] <= 0.5 * m["H_start"], team_diagnosis(summary, out)
    assert all(r["collisions"] == 0 for r in robots.values())


def test_a_child_stuck_on_a_broken_shared_memory_port_is_started_again(tmp_path):
    """A port file that a killed process left unsized makes the next participant that needs it
    wait for ever inside its first node (eProsima/Fast-DDS#3878): the launcher sees a child
    holding such a file open, kills it, removes the file and starts the child again."""
    from pathlib import Path

    from coverage_ros.cli.team.processes import ProcessSet, executable, ros_args

    domain = domain_id(24)
    # the user unicast ports of participants 0-3 in the domain (Fast DDS: 7400 + 250 domain + 11
    # + 2 id; the child is participant 1 when another socket on the machine holds participant
    # 0's UDP port), dated in the future so that the child's own clean-up of old broken files
    # leaves them
    ports = [Path(f"/dev/shm/fastrtps_port{7400 + 250 * domain + 11 + 2 * k}") for k in range(4)]
    later = time.time() + 3600.0
    for port in ports:
        port.unlink(missing_ok=True)
        port.touch()
        os.utime(port, (later, later))
    procs = ProcessSet(ros_env(domain), tmp_path)
    said: list[str] = []
    try:
        procs.start("world", executable("world_node") + ros_args(world="office"))
        restarted, deadline = [], time.monotonic() + 40.0
        while not restarted and time.monotonic() < deadline:
            time.sleep(1.0)
            restarted = procs.restart_stuck(said.append)
        log = tmp_path / "world.log"
        assert restarted == ["world"], log.read_text()
        assert len(said) == 1 and any(p.name in said[0] for p in ports), said
        deadline = time.monotonic() + 40.0
        while "world 'office'" not in log.read_text() and time.monotonic() < deadline:
            time.sleep(0.5)
        assert "world 'office'" in log.read_text()  # (the new process got past its start)
        assert procs.children["world"].alive and procs.stuck_on_broken_ports() == {}
    finally:
        procs.stop()
        for port in ports:
            if port.exists() and port.stat().st_size == 0:
                port.unlink()
