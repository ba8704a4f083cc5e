"""The team launcher's side of the fork server (:mod:`coverage_ros.nodes.preloaded`): robot
processes forked from one interpreter with their code loaded instead of a new interpreter each.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from coverage_ros.nodes.preloaded import PR_SET_CHILD_SUBREAPER, prctl

SERVER_MODULE = "coverage_ros.nodes.preloaded"


def become_subreaper() -> bool:
    """Make this process the parent of the processes the fork server starts for it (they are
    reparented to it when their first parent exits); whether the kernel agreed."""
    return prctl(PR_SET_CHILD_SUBREAPER, 1)


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
            except ChildProcessError:  # reaped elsewhere: gone, its code unknown
                self.returncode = 0
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
        child of the launcher."""
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
        it (the caller starts it anew)."""
        if self.broken or self.popen.poll() is not None:
            return None
        request = {"executable": executable, "argv": argv, "env": env, "log": str(log),
                   "name": name}
        stdin, stdout = self.popen.stdin, self.popen.stdout
        assert stdin is not None and stdout is not None
        try:
            stdin.write(json.dumps(request).encode() + b"\n")
            stdin.flush()
            reply = json.loads(stdout.readline() or b"{}")
        except (OSError, ValueError):
            reply = {}
        if "pid" not in reply:
            self.broken = True  # (its log says why)
            return None
        return ForkedProcess(int(reply["pid"]), argv)

    def close(self) -> None:
        """End the server (end of its input) and wait for it."""
        with contextlib.suppress(OSError):
            if self.popen.stdin is not None:
                self.popen.stdin.close()
        try:
            self.popen.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.popen.pid, signal.SIGKILL)
            self.popen.wait()
