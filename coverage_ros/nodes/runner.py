"""The life cycle all node executables share (``main`` of each node module).

Start-up errors (bad parameters, world files, maps) end the process with one line
``<name>: error: ...`` on stderr and exit code 2; so does a :class:`FatalConfigError` raised
later from a callback (e.g. a map that arrives and does not fit the configuration). SIGINT and
SIGTERM end it cleanly with code 0, also during start-up: there a signal interrupts whatever
is being built at once (a container creating a hundred robots would otherwise go on for
seconds), as it would end a process that had not started ROS yet.

The signals do not shut ROS down at once (rclpy's own handlers would: a callback publishing at
that moment failed, and every node's last words - a robot's zero velocity command that leaves
it standing, its summary on ``/rosout`` - went nowhere). They ask the spin loop to stop between
callbacks; the nodes' clean-up then runs with ROS still up, and ROS shuts down after it. A
second signal ends the process at once (exit code 128 + the signal's number). A process whose
parent had died when the signal came (the kernel's SIGTERM to a child of a killed launcher) gets
no second one: its clean-up is cut short :data:`SHUTDOWN_LIMIT` seconds after the signal (a
container of fifty robots took over 30 s on a loaded host). With its parent alive it is left to
finish (the launcher gives the rerun bridge 30 s to index its recording, then signals again).
While the nodes are being built, a process that asked for a signal on its parent's death asks
for SIGKILL instead (it has nothing to say yet, and a start-up can wait in native code that
holds the interpreter, e.g. on a shared-memory port a sibling's end left half made, where no
Python handler runs); once they are built it asks for its own signal again.

The executor is rclpy's ``EventsExecutor`` (``rclpy.experimental``, its dispatch loop in C++:
0.24-0.30x the CPU per message received in ``scripts/bench_executor``; a process of 16 robots
spent 0.21 ms per callback on it against 1.39 ms on the single-threaded one), unless the
environment variable ``COVERAGE_ROS_EXECUTOR`` is ``single``: then rclpy's
``SingleThreadedExecutor``. ``coverage-team --executor`` sets it for every process of a team.
Either is spun by ``spin_once`` in a loop that checks for a stop request (the EventsExecutor's
``spin()`` did not return on SIGINT here). Every node process logs which one it runs on.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from coverage_ros.errors import CoverageError
from coverage_ros.nodes.parameters import ParameterTable, usage_text
from coverage_ros.nodes.preloaded import PR_GET_PDEATHSIG, PR_SET_PDEATHSIG, prctl
from coverage_ros.nodes.shm_ports import warn_removed_ports

STARTUP_ERRORS = (CoverageError, ParameterException, OSError)
#: Values of ``COVERAGE_ROS_EXECUTOR`` (module docstring); the first is the default.
EXECUTORS = ("events", "single")
EXECUTOR_ENV = "COVERAGE_ROS_EXECUTOR"
#: [s] a process whose parent has died ends within this of its signal, whatever its clean-up
#: does (a live launcher waits 8 s before its second signal to the robots)
SHUTDOWN_LIMIT = 10.0
#: [s] after that the kernel ends it (SIGALRM), should native code hold the interpreter
SHUTDOWN_BACKSTOP = 5.0


def executor_kind() -> str:
    """The executor the environment asks for (:data:`EXECUTORS`)."""
    kind = os.environ.get(EXECUTOR_ENV, "") or EXECUTORS[0]
    if kind not in EXECUTORS:
        raise CoverageError(f"environment variable {EXECUTOR_ENV}={kind!r}: expected one of "
                            f"{', '.join(EXECUTORS)}")
    return kind


def _executor(kind: str):
    if kind == "events":
        from rclpy.experimental.events_executor import EventsExecutor
        return EventsExecutor()
    return SingleThreadedExecutor()


class LastWords:
    """A process's last messages (a robot's zero velocity): each is published, then waited on
    until every reliable subscriber has acknowledged it - the process ends next, and a sample
    lost on the way cannot be sent again once its writer is gone. All the nodes of a process
    (a robot container) share one ``budget`` [s] for that wait, counted from the first one: a
    subscriber that died without a word (still matched until its lease ends) never acknowledges."""

    def __init__(self, budget: float = 1.0) -> None:
        self.budget = budget
        self._deadline: float | None = None

    def publish(self, publisher, msg) -> bool:
        """Publish ``msg``; whether every subscriber acknowledged it within the budget."""
        publisher.publish(msg)
        if self._deadline is None:
            self._deadline = time.monotonic() + self.budget
        left = max(0.0, self._deadline - time.monotonic())
        return publisher.wait_for_all_acked(Duration(seconds=left))


#: This process's (see :class:`LastWords`).
LAST_WORDS = LastWords()


class StartupInterrupted(BaseException):
    """SIGINT or SIGTERM while the nodes are being built (not an Exception: nothing on the way
    may catch it)."""


class StopRequest:
    """SIGINT / SIGTERM handlers for the life of a node process (module docstring): during
    start-up a signal interrupts it (:class:`StartupInterrupted`); afterwards the first signal
    asks the spin loop to stop, the next one shuts ROS down."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.asked = False
        self.starting = True
        self._before = {sig: signal.signal(sig, self._on_signal) for sig in self.SIGNALS}
        self._parent = os.getppid()
        self._watchdog: threading.Timer | None = None

    def _on_signal(self, signum, frame) -> None:
        if self.starting:
            self.starting = False
            raise StartupInterrupted
        if self.asked:
            # At once: shutting rclpy down from a handler deadlocked when the signal had
            # interrupted rclpy itself (a robot container waited for ever).
            os._exit(128 + signum)
        self.asked = True
        if os.getppid() != self._parent:  # (orphaned: no second signal will come)
            self._arm(signum)

    def _arm(self, signum: int) -> None:
        self._watchdog = threading.Timer(SHUTDOWN_LIMIT, _cut_short, args=(signum,))
        self._watchdog.daemon = True
        self._watchdog.start()
        signal.signal(signal.SIGALRM, signal.SIG_DFL)
        signal.alarm(int(SHUTDOWN_LIMIT + SHUTDOWN_BACKSTOP + 0.999))

    def restore(self) -> None:
        """The handlers as before; a shutdown deadline armed is called off."""
        if self._watchdog is not None:
            self._watchdog.cancel()
            signal.alarm(0)
        for sig, handler in self._before.items():
            signal.signal(sig, handler)


def parent_death_signal() -> int:
    """The signal this process asked for on its parent's death (0: none, or unknown)."""
    value = ctypes.c_int(0)
    return value.value if prctl(PR_GET_PDEATHSIG, ctypes.byref(value)) else 0


def _cut_short(signum: int) -> None:
    print(f"parent gone and shutdown still running {SHUTDOWN_LIMIT:g} s after the signal: "
          "ending now",
          file=sys.stderr, flush=True)
    os._exit(128 + signum)


def _spin(executor, context, stop: StopRequest) -> None:
    # (spin_once with a timeout: Python runs the signal handler when the call returns; the
    # EventsExecutor's spin() did not return on SIGINT here)
    while context.ok() and not stop.asked:
        executor.spin_once(timeout_sec=0.2)


class FatalConfigError(CoverageError):
    """A configuration error found after start-up (e.g. when the map arrives): ends the node."""


def wants_help(argv: list[str]) -> bool:
    """``-h`` or ``--help`` among the arguments before ``--ros-args`` (program name first)."""
    own = argv[1:argv.index("--ros-args")] if "--ros-args" in argv else argv[1:]
    return "-h" in own or "--help" in own


def run_node(name: str, make_node: Callable[[], Node], args=None,
             cleanup: Callable[[Any], None] | None = None,
             parameters: ParameterTable | None = None) -> int:
    """Initialise rclpy, build the node, spin it until shutdown; the process exit code.

    ``cleanup(node)`` runs before the node is destroyed, whatever ended the spin; an error in
    it is reported on stderr and does not change the exit code."""
    return run_nodes(name, lambda: [make_node()], args, cleanup, parameters)


def run_nodes(name: str, make_nodes: Callable[[], list[Node]], args=None,
              cleanup: Callable[[Any], None] | None = None,
              parameters: ParameterTable | None = None) -> int:
    """:func:`run_node` for several nodes in one process (the composition idiom): all of them
    on one executor (module docstring); ``cleanup`` runs for each before it is destroyed.
    ``-h`` / ``--help`` before any ROS arguments prints the usage and the node's
    ``parameters``."""
    if wants_help(sys.argv if args is None else args):
        print(usage_text(name, parameters or {}))
        return 0
    try:
        kind = executor_kind()
    except CoverageError as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        return 2
    warn_removed_ports(name)
    on_parent_death = parent_death_signal()
    stop = StopRequest()
    try:
        if on_parent_death:  # (module docstring: the kernel ends a start-up stuck in native code)
            prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        nodes = make_nodes()
        stop.starting = False
    except StartupInterrupted:
        # Ends here, without shutting ROS down or tearing the half-built nodes down: either
        # could wait on DDS threads, and a launcher that died relies on this process going.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)
    except STARTUP_ERRORS as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        rclpy.try_shutdown()
        stop.restore()
        return 2
    if on_parent_death:  # (had the parent died before this, SIGKILL would have come)
        prctl(PR_SET_PDEATHSIG, on_parent_death)
    executor = _executor(kind)
    nodes[0].get_logger().info(f"executor: {kind} ({EXECUTOR_ENV}; default {EXECUTORS[0]})")
    for node in nodes:
        executor.add_node(node)
    code = 0
    try:
        _spin(executor, nodes[0].context, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except FatalConfigError as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        code = 2
    except Exception:
        # ROS shut down under a callback that was publishing: a shutdown, not a crash.
        if nodes[0].context.ok():
            raise
    finally:
        for node in nodes:
            if cleanup is not None:
                try:
                    cleanup(node)
                except Exception as exc:  # e.g. the context went away mid-publish
                    print(f"{name}: warning: while shutting down: {exc!r}", file=sys.stderr)
            executor.remove_node(node)
            node.destroy_node()
        executor.shutdown(timeout_sec=0)
        rclpy.try_shutdown()
        stop.restore()
    return code
