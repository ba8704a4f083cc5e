"""The team launcher's side of the fork server (:mod:`coverage_ros.nodes.preloaded`): robot
processes forked from one interpreter with their code loaded instead of a new interpreter each.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

from coverage_ros.nodes.preloaded import PR_SET_CHILD_SUBREAPER, prctl

SERVER_MODULE = "coverage_ros.nodes.preloaded"
#: [s] the server answers a request within this (its first answer waits for its imports)
REPLY_WAIT = 120.0
#: Exit code of a forked process whose real one could not be had.
UNKNOWN_EXIT = 255


def become_subreaper(on: bool = True) -> bool:
    """Make this process the parent of the processes the fork server starts for it (they are
    reparented to it when their first parent exits), or (``on`` False) no longer; whether the
    kernel agreed."""
    return prctl(PR_SET_CHILD_SUBREAPER, int(on))


class ForkedProcess:
    """The part of :class:`subprocess.Popen` the launcher uses, for a process the fork server
    started (a child of this process once reparented)."""

    def __init__(self, pid: int, args: list[str]) -> None:
        self.pid = pid
        self.args = args
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            try:
                pid, status = os.waitpid(self.pid, os.WNOHANG)
            except ChildProcessError:  # not this process's child, or reaped elsewhere: gone,
                self.returncode = UNKNOWN_EXIT  # its code unknown (counts as a failure)
            else:
                if pid == self.pid:
                    self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            if deadline is not None and time.monotonic() >= deadline:
                raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
            time.sleep(0.01)
        assert self.returncode is not None
        return self.returncode


class ForkServer:
    """The launcher's side: starts the server and asks it for processes."""

    def __init__(self, env: dict[str, str], log: Path, setup) -> None:
        """``env``: the children's environment (the modules are imported under it); ``log``:
        the server's own output; ``setup``: what the server runs before exec, as for every
        child of the launcher. OSError if it cannot be started."""
        self.log = log
        with open(log, "wb") as fh:
            self.popen = subprocess.Popen(
                [sys.executable, "-m", SERVER_MODULE, str(os.getpid())], env=env,
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=fh,
                start_new_session=True, preexec_fn=setup)
        self.broken = False

    def spawn(self, name: str, executable: str, argv: list[str], env: dict[str, str],
              log: Path) -> ForkedProcess | None:
        """Process ``name`` (as ``top`` shows it) running ``executable`` with ``argv`` (its
        ``sys.argv``) and ``env``, output appended to ``log``; None if the server cannot start
        it (the caller starts it anew; the server is not asked again). Call it with SIGINT and
        SIGTERM held until the process is recorded (:class:`~.processes.ProcessSet` does): a
        request answered but never read would leave a process nobody knows of and the next
        answer out of step."""
        if self.broken or self.popen.poll() is not None:
            return None
        request = {"executable": executable, "argv": argv, "env": env, "log": str(log),
                   "name": name}
        assert self.popen.stdin is not None
        try:
            self.popen.stdin.write(json.dumps(request).encode() + b"\n")
            self.popen.stdin.flush()
            reply = json.loads(self._reply(REPLY_WAIT) or b"{}")
        except (OSError, ValueError):
            reply = {}
        if "pid" not in reply:
            self.broken = True
            print(f"coverage-team: the fork server did not start {name} (see {self.log}): "
                  "robot processes start as new interpreters from now on", file=sys.stderr,
                  flush=True)
            self.close()
            return None
        return ForkedProcess(int(reply["pid"]), argv)

    def _reply(self, timeout: float) -> bytes:
        """One line from the server, b"" if none came within ``timeout`` [s]."""
        assert self.popen.stdout is not None
        fd = self.popen.stdout.fileno()
        deadline = time.monotonic() + timeout
        line = b""
        while not line.endswith(b"\n"):
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                return b""
            chunk = os.read(fd, 4096)
            if not chunk:
                return b""
            line += chunk
        return line

    def close(self) -> None:
        """End the server (end of its input) and wait for it."""
        for stream in (self.popen.stdin, self.popen.stdout):
            with contextlib.suppress(OSError):
                if stream is not None:
                    stream.close()
        try:
            self.popen.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.popen.pid, signal.SIGKILL)
            self.popen.wait()
