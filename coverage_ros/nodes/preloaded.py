"""Robot processes forked from one interpreter that has their code loaded: the team launcher's
fork server (:mod:`coverage_ros.cli.team.forkserver` starts it and talks to it).

    python -m coverage_ros.nodes.preloaded LAUNCHER_PID

loads :data:`MODULES`, then reads one JSON request per line on stdin - ``{"executable":
"robot_node", "argv": [...], "env": {...}, "log": path, "name": "robot_3"}`` - and answers
each with ``{"pid": N}`` (or ``{"error": text}``) on stdout. The process started is what ``ros2
run coverage_ros <executable>`` would run - the module's ``main()`` with that ``sys.argv`` and
environment - without an interpreter of its own to start and numpy, scipy and rclpy to import
again (about 1.2 s of CPU per robot process). Forked twice, it is reparented to the launcher
(a child subreaper), which waits for it as for its other children; like those it runs in a
session of its own, asks for SIGTERM when the launcher dies (Linux ``PR_SET_PDEATHSIG``) and
appends its output to its log file; ``name`` is what ``top`` shows for it, and this server's
output (``forkserver.log`` in the run's logs) names each process it started.

This process has no ROS context and runs no code between requests. What its imports leave
running is idle when it forks: OpenBLAS stops its thread pools around a fork (its own
``pthread_atfork`` handlers), and the two native threads that loading rclpy's libraries
starts wait on a condition (a forked process has only the thread that forked it). A forked
process reads the environment it is given wherever rcl, Fast DDS and the nodes read theirs (at
start-up, after the fork); only what the interpreter and the imports read at their start
(``PYTHON*``, ``OPENBLAS_NUM_THREADS``) is the server's - the launcher's. It ends as the
interpreter would, with the exit functions run and the output flushed, but without waiting
for non-daemon threads (the nodes' threads are daemons).
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import importlib
import json
import os
import signal
import sys
import time
import traceback
from typing import IO

#: The executables served, by the module whose ``main()`` each one runs.
MODULES = {"robot_node": "coverage_ros.nodes.robot_node",
           "robot_container": "coverage_ros.nodes.robot_container"}
PR_SET_PDEATHSIG, PR_GET_PDEATHSIG, PR_SET_NAME, PR_SET_CHILD_SUBREAPER = 1, 2, 15, 36  # prctl.h
#: [s] a forked process waits this long at most to be reparented to the launcher
REPARENT_WAIT = 5.0


def prctl(option: int, value: object) -> bool:
    """Linux ``prctl(option, value)`` (an int, bytes or a ctypes pointer); whether it succeeded."""
    with contextlib.suppress(Exception):
        return ctypes.CDLL("libc.so.6", use_errno=True).prctl(option, value) == 0
    return False


def serve(launcher: int, requests: IO[bytes], replies: IO[bytes]) -> int:
    """Load :data:`MODULES`, then answer requests until the input ends."""
    for module in MODULES.values():
        importlib.import_module(module)
    for line in requests:
        reply: dict[str, int | str]
        try:
            reply = {"pid": _spawn(json.loads(line), launcher)}
        except (OSError, ValueError, KeyError, TypeError) as exc:
            reply = {"error": f"{type(exc).__name__}: {exc}"}
            print(f"preloaded: {reply['error']}", file=sys.stderr, flush=True)
        replies.write(json.dumps(reply).encode() + b"\n")
        replies.flush()
    return 0


def _spawn(request: dict, launcher: int) -> int:
    """Fork twice: the grandchild becomes the process asked for and sends its PID once it
    leads a session of its own (a signal to its process group reaches it from then on); the
    child exits at once, so that the grandchild is reparented to the launcher. The PID."""
    if request["executable"] not in MODULES:
        raise KeyError(f"not served here: {request['executable']}")
    sys.stdout.flush()
    sys.stderr.flush()
    read, write = os.pipe()
    middle = os.fork()
    if middle == 0:
        try:
            os.close(read)
            if os.fork() == 0:
                try:
                    os.setsid()
                    os.write(write, str(os.getpid()).encode())
                    os.close(write)
                    _become(request, launcher)
                finally:
                    os._exit(1)  # (what _become's own handling let through)
        finally:
            os._exit(0)
    os.close(write)
    with os.fdopen(read, "rb") as fh:
        text = fh.read()  # (until the grandchild has closed its end)
    os.waitpid(middle, 0)
    if not text:
        raise OSError("fork failed")
    pid = int(text)
    print(f"preloaded: {request.get('name', request['executable'])} is process {pid}",
          file=sys.stderr, flush=True)
    return pid


def _become(request: dict, launcher: int) -> None:
    """In the grandchild: set up as the launcher sets up its children, then run the
    executable's ``main()`` and exit as the interpreter would (never returns)."""
    code: int = 1
    try:
        deadline = time.monotonic() + REPARENT_WAIT
        while os.getppid() != launcher:
            if time.monotonic() > deadline:
                os._exit(0)
            time.sleep(0.001)
        prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        # its name in top and ps -o comm (its command line stays the server's)
        prctl(PR_SET_NAME, str(request.get("name", request["executable"])).encode()[:15])
        if os.getppid() != launcher:  # the launcher died before the request: no signal comes
            os._exit(0)
        log = os.open(request["log"], os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        os.dup2(log, 1)
        os.dup2(log, 2)
        os.close(log)
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        os.close(null)
        sys.stdin = os.fdopen(0)  # (the server's buffered requests are not its input)
        os.environ.clear()
        os.environ.update(request["env"])
        sys.argv = list(request["argv"])
        module = importlib.import_module(MODULES[request["executable"]])
        result = module.main()
        code = 0 if result is None else int(result)
    except SystemExit as exc:
        code = _exit_code(exc.code)
    except KeyboardInterrupt:  # as the interpreter ends on one: by SIGINT
        _finish()
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        os.kill(os.getpid(), signal.SIGINT)
    except BaseException:
        traceback.print_exc()
        code = 1
    _finish()
    os._exit(code)


def _exit_code(value) -> int:
    if value is None:
        return 0
    if isinstance(value, int):
        return value
    print(value, file=sys.stderr)
    return 1


def _finish() -> None:
    """What the interpreter does at exit: the exit functions, the output flushed."""
    with contextlib.suppress(BaseException):
        atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(BaseException):
            stream.flush()


if __name__ == "__main__":
    sys.exit(serve(int(sys.argv[1]), sys.stdin.buffer, sys.stdout.buffer))
