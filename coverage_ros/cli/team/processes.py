"""Child processes of the team launcher: one per node, what ``ros2 run`` would start.

Robot processes (``robot_node``, ``robot_container``) come from the launcher's fork server
(:mod:`.forkserver`) when one is asked for: the same executable with the same arguments and
environment, forked from an interpreter with their code loaded. Every child runs in its own
process group (so a Ctrl-C in the terminal reaches only the launcher, which then stops the
children in order), asks the kernel to SIGTERM it if the launcher dies (Linux
``PR_SET_PDEATHSIG``; a child whose launcher died before it asked ends at once), and writes its
output to a log file. Processes are stopped by PID/process group only: SIGINT (a clean rclpy
shutdown), then SIGTERM, then SIGKILL.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from coverage_ros.cli.team.forkserver import ForkedProcess, ForkServer, become_subreaper
from coverage_ros.nodes.preloaded import MODULES as SERVED
from coverage_ros.nodes.preloaded import PR_SET_PDEATHSIG, prctl
from coverage_ros.nodes.shm_ports import held_broken_ports, restarted_env

PACKAGE = "coverage_ros"


def _child_setup(parent: int) -> Callable[[], None]:
    """What a child does between fork and exec (after ``setsid``): ask for SIGTERM when
    ``parent`` (the launcher's PID) dies."""

    def setup() -> None:
        prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent:  # the launcher died before the request: no signal comes
            os._exit(0)

    return setup


def executable(name: str) -> list[str]:
    """Command for a package executable: ``<prefix>/lib/coverage_ros/<name>`` found through the
    ament index (the ``ros2 run`` layout), else the Python module in this environment."""
    with contextlib.suppress(Exception):
        from ament_index_python.packages import get_package_prefix

        path = Path(get_package_prefix(PACKAGE)) / "lib" / PACKAGE / name
        if path.is_file() and os.access(path, os.X_OK):
            return [str(path)]
    modules = {**SERVED, "world_node": "coverage_ros.nodes.world_node",
               "rerun_bridge": "coverage_ros.nodes.rerun_bridge",
               "marker_node": "coverage_ros.nodes.marker_node"}
    return [sys.executable, "-m", modules[name]]


def ros_args(namespace: str | None = None, **params) -> list[str]:
    """``--ros-args [-r __ns:=NS] -p name:=value ...``; values are written so that rcl's YAML
    parser reads back exactly them (a string that YAML would read as something else, such as
    ``{method: paper}``, is quoted)."""
    out = ["--ros-args"]
    if namespace:
        out += ["-r", f"__ns:={namespace}"]
    for key, value in params.items():
        out += ["-p", f"{key}:={parameter_text(value)}"]
    return out


def parameter_text(value) -> str:
    """How a parameter value is written after ``-p name:=``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        if not value:
            return "''"
        try:
            plain = yaml.safe_load(value) == value
        except yaml.YAMLError:
            plain = False
        return value if plain else json.dumps(value)
    return repr(value)


@dataclass
class Child:
    name: str
    popen: subprocess.Popen | ForkedProcess
    log: Path
    cmd: list[str]
    extra_env: dict[str, str] | None = None

    @property
    def alive(self) -> bool:
        return self.popen.poll() is None


class ProcessSet:
    """The launcher's children, started and stopped together."""

    def __init__(self, env: dict[str, str], log_dir: Path, fork_server: bool = False) -> None:
        """``fork_server``: robot processes come from a fork server (:mod:`.forkserver`; this
        process is a child subreaper until :meth:`close`), else - or if it cannot be had -
        each from its executable."""
        self.env = env
        self.log_dir = log_dir
        self.children: dict[str, Child] = {}
        self.server: ForkServer | None = None
        if fork_server and become_subreaper():
            try:
                self.server = ForkServer(env, log_dir / "forkserver.log",
                                         _child_setup(os.getpid()))
            except OSError as exc:
                become_subreaper(False)
                print(f"coverage-team: no fork server ({exc}): robot processes start as new "
                      "interpreters", file=sys.stderr, flush=True)

    def start(self, name: str, cmd: list[str], append: bool = False,
              extra_env: dict[str, str] | None = None) -> Child:
        """Start ``cmd`` as child ``name`` (replacing a dead one of that name); its output goes
        to ``<log_dir>/<name>.log`` (``append``: after what the previous one wrote);
        ``extra_env`` is added to the set's environment for this child only."""
        log = self.log_dir / f"{name}.log"
        env = {**self.env, **(extra_env or {})}
        served = _served(cmd)
        if self.server is not None and served is not None:
            log.open("ab" if append else "wb").close()  # (there at once, as for the others)
            with _signals_held():  # (the process is known once it exists)
                forked = self.server.spawn(name, served[0], served[1], env, log)
                if forked is not None:
                    child = Child(name, forked, log, list(cmd), extra_env)
                    self.children[name] = child
                    return child
        with open(log, "ab" if append else "wb") as fh:
            popen = subprocess.Popen(cmd, env=env, stdout=fh, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, start_new_session=True,
                                     preexec_fn=_child_setup(os.getpid()))
        child = Child(name, popen, log, list(cmd), extra_env)
        self.children[name] = child
        return child

    def start_again(self, name: str) -> Child:
        """Start child ``name`` again, in place of its killed process: its command and
        environment, its log appended to, Fast DDS on UDP alone
        (:func:`~coverage_ros.nodes.shm_ports.restarted_env`)."""
        child = self.children[name]
        extra = child.extra_env or {}
        return self.start(name, child.cmd, append=True,
                          extra_env={**extra, **restarted_env({**self.env, **extra})})

    def stuck_on_broken_ports(self) -> dict[str, list[Path]]:
        """Children (by name) that hold a broken Fast DDS shared-memory port open: they wait
        on it for ever (:mod:`coverage_ros.nodes.shm_ports`)."""
        stuck = {}
        for name, child in self.children.items():
            if child.alive:
                held = held_broken_ports(Path(f"/proc/{child.popen.pid}/fd"))
                if held:
                    stuck[name] = held
        return stuck

    def restart_stuck(self, say, recheck: float = 1.0) -> list[str]:
        """Children stuck on a broken port now and ``recheck`` seconds later (a port being made
        this moment is marked by then) are killed, the files removed and the children started
        again, each with one line through ``say``; their names."""
        first = self.stuck_on_broken_ports()
        if not first:
            return []
        time.sleep(recheck)
        stuck = {n: p for n, p in self.stuck_on_broken_ports().items() if n in first}
        for name, paths in stuck.items():
            child = self.children[name]
            with contextlib.suppress(ProcessLookupError):
                os.killpg(child.popen.pid, signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):
                child.popen.wait(timeout=5.0)
            for path in paths:
                with contextlib.suppress(OSError):
                    path.unlink()
            say(f"coverage-team: {name} waited on a broken Fast DDS shared-memory file "
                f"({', '.join(p.name for p in paths)}) that a killed process left: removed it "
                f"and started {name} again")
            self.start_again(name)
        return list(stuck)

    def signal(self, name: str, sig: int) -> None:
        child = self.children.get(name)
        if child is not None and child.alive:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(child.popen.pid, sig)

    def stop(self, names: list[str] | None = None, timeout: float = 8.0) -> None:
        """SIGINT, wait; SIGTERM, wait; SIGKILL - for the given children (default all)."""
        names = [n for n in (names or list(self.children)) if n in self.children]
        for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, min(3.0, timeout)),
                          (signal.SIGKILL, 3.0)):
            alive = [n for n in names if self.children[n].alive]
            if not alive:
                break
            for n in alive:
                self.signal(n, sig)
            deadline = time.monotonic() + wait
            while time.monotonic() < deadline and any(self.children[n].alive for n in alive):
                time.sleep(0.05)
        for n in names:
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.children[n].popen.wait(timeout=1.0)

    def close(self) -> None:
        """Stop every child, then the fork server; this process is no subreaper any more."""
        self.stop()
        if self.server is not None:
            self.server.close()
            self.server = None
            become_subreaper(False)

    def failed(self) -> list[Child]:
        """Children that exited on their own with a non-zero code."""
        return [c for c in self.children.values()
                if not c.alive and c.popen.returncode not in (0, None, -2, -15)]

    def tail(self, child: Child, lines: int = 5) -> str:
        try:
            text = child.log.read_text(errors="replace").strip().splitlines()
        except OSError:
            return ""
        return "\n".join(text[-lines:])


@contextlib.contextmanager
def _signals_held():
    """SIGINT and SIGTERM handled after the block instead of within it (in the main thread,
    where Python runs signal handlers; elsewhere the block runs as it is)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    before = {sig: signal.signal(sig, lambda signum, _frame: held.append(signum))
              for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
        for signum in dict.fromkeys(held):
            handler = before[signal.Signals(signum)]
            if callable(handler):
                handler(signum, None)
            elif handler == signal.SIG_DFL:
                os.kill(os.getpid(), signum)


def _served(cmd: list[str]) -> tuple[str, list[str]] | None:
    """``(executable, sys.argv)`` of a command the fork server runs, else None."""
    for name in SERVED:
        prefix = executable(name)
        if cmd[:len(prefix)] == prefix:
            return name, [prefix[-1] if len(prefix) == 1 else name, *cmd[len(prefix):]]
    return None


class ProcessStats:
    """CPU [% of one core] and memory (RSS) of every child process, sampled once a second."""

    PERIOD = 1.0  # [s] wall

    def __init__(self, procs) -> None:
        import psutil

        self.procs = procs
        self.handles = {}
        for name, child in procs.children.items():
            with contextlib.suppress(psutil.Error):
                self.handles[name] = psutil.Process(child.popen.pid)
                self.handles[name].cpu_percent(None)  # starts the CPU time window
        self.cpu: dict[str, list[float]] = {n: [] for n in self.handles}
        self.rss: dict[str, float] = dict.fromkeys(self.handles, 0.0)
        self.last = time.monotonic()

    def sample(self, now: float) -> None:
        import psutil

        if now - self.last < self.PERIOD:
            return
        self.last = now
        for name, h in self.handles.items():
            with contextlib.suppress(psutil.Error):
                self.cpu[name].append(h.cpu_percent(None))
                self.rss[name] = max(self.rss[name], h.memory_info().rss / 2**20)

    def report(self, robots: int | None = None) -> dict:
        """Per process: mean CPU [% of one core] and peak RSS [MB]; ``robot_mean``: their mean
        over the robot processes (``robot_<id>`` and ``robots_<a>-<b>``); ``per_robot``: all
        robot processes' CPU and peak RSS over the number of ``robots``."""
        per = {n: {"cpu_percent": round(float(np.mean(c)), 1) if c else None,
                   "rss_mb_peak": round(self.rss[n], 1)} for n, c in self.cpu.items()}
        procs = [v for n, v in per.items()
                 if n.startswith(("robot_", "robots_")) and v["cpu_percent"] is not None]

        def mean(key: str):
            return round(float(np.mean([r[key] for r in procs])), 1) if procs else None

        out = {"per_process": per, "robot_processes": len(procs),
               "robot_mean": {"cpu_percent": mean("cpu_percent"),
                              "rss_mb_peak": mean("rss_mb_peak")}}
        if robots and procs:
            out["per_robot"] = {
                "cpu_percent": round(sum(r["cpu_percent"] or 0.0 for r in procs) / robots, 2),
                "rss_mb": round(sum(r["rss_mb_peak"] or 0.0 for r in procs) / robots, 1)}
        return out
