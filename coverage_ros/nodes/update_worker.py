"""A robot's coverage updates on a thread of their own, within a CPU budget, taking turns with
the other robots of its process.

Threads. rclpy's executor runs every callback of a node on one thread (the *executor thread*).
A robot's coverage update can take longer than its tracking period, so it runs on the
:class:`UpdateWorker`'s own thread instead; the rules that keep that safe:

1. the worker runs one call at a time, started only from the executor thread
   (:meth:`UpdateWorker.request`), so updates never overlap;
2. an update reads its inputs as a snapshot taken under the controller's lock and commits its
   result under the same lock; tracking (executor thread) takes that lock for each command, so
   it sees either the old or the new plan, never half of one
   (:class:`coverage_ros.core.control.controller.RobotController`);
3. the neighbour table has its own lock: states arrive on the executor thread while an update
   reads the table (:class:`coverage_ros.core.control.neighbours.NeighbourTable`);
4. publishing from the worker thread is allowed (rclpy publishers are thread-safe), but a
   publish may fail once the context is shut down, which the worker treats as shutdown;
5. :class:`WarnThrottle` may be called from any thread.

rclpy's ``MultiThreadedExecutor`` with a ``MutuallyExclusiveCallbackGroup`` for the update
timer would give the same separation, but it hands *every* callback to a thread pool, which
costs more CPU per message (``scripts/bench_executor``); a team on two cores is bound by that
per-message cost, so robot_node keeps the single-threaded executor and one update thread.
"""

from __future__ import annotations

import heapq
import itertools
import math
import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np

#: [s] CPU time an update may borrow ahead of its load (see UpdateWorker).
UPDATE_BURST = 1.0
#: Calls whose CPU times :class:`UpdateWorker` keeps for its summary's median (bounded memory).
RECENT_CALLS = 4096
_LIBC: list = []  # [the C library, or None where it has no malloc_trim], once looked up


def release_free_memory() -> None:
    """Hand heap memory that is free again back to the operating system (glibc's
    ``malloc_trim``; nothing elsewhere). glibc keeps freed heap pages, so without it a robot's
    RSS stays at the high-water mark of its largest update ever - e.g. of the large cell it had
    while a neighbour was restarting - instead of following what it uses (~1 ms)."""
    if not _LIBC:
        import ctypes
        import ctypes.util

        try:
            libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
            _LIBC.append(libc if hasattr(libc, "malloc_trim") else None)
        except OSError:
            _LIBC.append(None)
    if _LIBC[0] is not None:
        _LIBC[0].malloc_trim(0)


class UpdatePool:
    """The CPU-time credit of the update workers of one process (a token bucket): it grows by
    the sum of their loads per wall second up to the largest of their bursts (where it
    starts), and every call spends its CPU time; a call may start while the credit is not
    negative. One worker alone is the bucket of one robot. The robots of a container pool
    their shares, so that a robot with a large cell (a whole-map search) can use what robots
    with small cells leave; the worker whose turn it is (:class:`UpdateTurns`: the robot that
    waited longest) waits for the credit, so no cheap robot asking meanwhile goes before it.
    The burst is one robot's, not the sum of theirs: with 16 robots' bursts, cheap robots
    updating every control period spent 16 s of CPU before the shares bound, and the team's
    first minute saturated the machine (64 robots: rtf 0.96). Thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.load = 0.0  # [CPU s / s]
        self.burst = 0.0  # [CPU s]
        self._credit = 0.0
        self._credit_at = time.monotonic()
        self.members = 0

    def join(self, load: float, burst: float) -> None:
        """Add a worker's load and burst."""
        with self._lock:
            self._refill(time.monotonic())
            self.load += load
            self._credit += max(burst - self.burst, 0.0)
            self.burst = max(self.burst, burst)
            self.members += 1

    def delay(self, now: float | None = None) -> float:
        """[s] until the credit is no longer negative at ``now`` (monotonic; default: the
        time of the call); 0 when a call may start."""
        with self._lock:
            credit = self._refill(time.monotonic() if now is None else now)
            if credit >= 0:
                return 0.0
            return -credit / self.load if self.load > 0 else math.inf

    def spend(self, cpu: float, at: float) -> None:
        """Take ``cpu`` seconds of a call that started at ``at`` (monotonic) from the credit."""
        with self._lock:
            self._refill(at)
            self._credit -= cpu

    def _refill(self, now: float) -> float:
        if now > self._credit_at:
            self._credit = min(self.burst, self._credit + self.load * (now - self._credit_at))
            self._credit_at = now
        return self._credit


class UpdateTurns:
    """At most ``slots`` calls of the update workers of one process at once, and when a slot
    frees the waiting call whose worker's last call started longest ago goes next (a
    semaphore would wake any of them: robots with cheap updates, asking every control period,
    kept one with a costly update waiting). A freed slot is handed to that one waiter (no
    wake-up of all of them: each would take the GIL from the executor thread). Thread-safe."""

    def __init__(self, slots: int) -> None:
        self._free = slots
        self._lock = threading.Lock()
        self._waiting: list[tuple[float, int, threading.Event]] = []  # a heap
        self._tickets = itertools.count()
        self._closed = False

    def acquire(self, last_start: float = -math.inf) -> None:
        """Wait for a slot; ``last_start`` [s monotonic] of the worker's last call (-inf: none
        yet) orders the waiting calls."""
        with self._lock:
            if self._closed:
                return
            if self._free > 0 and not self._waiting:
                self._free -= 1
                return
            handed = threading.Event()
            heapq.heappush(self._waiting, (last_start, next(self._tickets), handed))
        handed.wait()

    def release(self) -> None:
        with self._lock:
            if self._waiting:
                heapq.heappop(self._waiting)[2].set()  # the slot passes on
            else:
                self._free += 1

    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        """The process ends: every waiting call goes on at once (its worker sees that the
        turns are closed and returns), and no call waits any more - a robot of a container
        queued behind forty others must not hold up the process's exit."""
        with self._lock:
            self._closed = True
            for _, _, handed in self._waiting:
                handed.set()
            self._waiting.clear()


class UpdateWorker:
    """Runs ``run(now)`` on its own thread when asked, one call at a time, and keeps the CPU
    time of the calls within ``load`` of one core on average (see the module's thread rules).

    A CPU-time credit (a token bucket, :class:`UpdatePool`) grows by ``load`` per wall second
    up to ``burst`` seconds and every call spends its CPU time; a call may start while the
    credit is not negative. So by any start time t, the calls before it used at most
    ``burst + load * (t - created)`` seconds of CPU, and a single costly call (the first,
    cold one, or one in a very large cell) is absorbed by the credit instead of holding back
    the next updates for c / load seconds. ``pool``: the bucket the workers of one process
    share (robot_container; its load is the sum of theirs, its burst the largest of theirs):
    the guarantee then holds for their calls together. A call asked for while the credit is
    negative waits for it (and then runs at ``clock``'s time, when given). An exception raised
    by a call goes to ``on_error`` and the worker carries on. ``slots``: the
    :class:`UpdateTurns` of the workers of one process, so that only that many of their calls
    run at once (robot_container: each runnable update thread takes turns at the GIL with the
    executor thread, whose tracking must not wait for them), the longest-waiting robot first."""

    def __init__(self, run: Callable[[float], None], load: float,
                 on_error: Callable[[Exception], object] | None = None,
                 burst: float = UPDATE_BURST,
                 slots: UpdateTurns | None = None,
                 pool: UpdatePool | None = None,
                 clock: Callable[[], float] | None = None) -> None:
        self._run = run
        self._on_error = on_error
        self._slots = slots  # shared by the workers of one process: calls that may run at once
        self._load = load
        self.burst = burst
        self._pool = pool if pool is not None else UpdatePool()
        self._pool.join(load, burst)
        self._clock = clock  # node time when a call starts (else: when it was asked for)
        self._wake = threading.Event()
        self._closed = threading.Event()
        self._busy = False
        self._now = 0.0
        self.created = time.monotonic()
        self.calls = 0
        self.cpu_ms: deque[float] = deque(maxlen=RECENT_CALLS)  # CPU time of recent calls
        self.cpu_ms_max = 0.0
        self.starts: deque[float] = deque(maxlen=RECENT_CALLS)  # [s] monotonic, recent calls
        self.first_start = math.nan  # [s] monotonic start of the first call
        self._thread = threading.Thread(target=self._loop, name="coverage-update", daemon=True)
        self._thread.start()

    def request(self, now: float) -> bool:
        """Ask for a call for node time ``now`` (``clock``'s time when it starts, if given);
        False if one is running or waiting for its turn or the credit. A solo worker's call
        waits only for the credit; pooled ones also take turns (:class:`UpdateTurns`)."""
        if self._busy or self._closed.is_set():
            return False
        self._busy, self._now = True, now
        self._wake.set()
        return True

    def _loop(self) -> None:
        while True:
            self._wake.wait()
            self._wake.clear()
            if self._closed.is_set():
                return
            if self._slots is not None:
                self._slots.acquire(self.starts[-1] if self.starts else -math.inf)
            try:
                if self._closed.is_set() or (self._slots is not None and self._slots.closed):
                    return  # (closed while waiting for the turn: the process ends)
                while (wait := self._pool.delay()) > 0:
                    if self._closed.wait(min(wait, 1.0)):
                        return
                start, cpu0 = time.monotonic(), time.thread_time()
                try:
                    self._run(self._clock() if self._clock is not None else self._now)
                except Exception as exc:
                    if self._on_error is not None:
                        self._on_error(exc)
            finally:
                if self._slots is not None:
                    self._slots.release()
            release_free_memory()
            cpu = time.thread_time() - cpu0
            self._pool.spend(cpu, start)
            self.calls += 1
            self.cpu_ms.append(1e3 * cpu)
            self.cpu_ms_max = max(self.cpu_ms_max, 1e3 * cpu)
            if self.calls == 1:
                self.first_start = start
            self.starts.append(start)
            self._busy = False

    def summary(self) -> str:
        """One line on the calls so far: count, mean, median and longest period (of the
        recent calls), CPU per call."""
        n = self.calls
        if n == 0:
            return "no coverage updates"
        period = (self.starts[-1] - self.first_start) / (n - 1) if n > 1 else math.nan
        gaps = np.diff(np.asarray(self.starts))
        median = float(np.median(gaps)) if len(gaps) else math.nan
        return (f"{n} coverage updates, one every {period:.2f} s wall (median {median:.2f} "
                f"s, longest {gaps.max() if len(gaps) else math.nan:.2f} s); CPU per update "
                f"median {np.median(np.asarray(self.cpu_ms)):.1f} ms (last "
                f"{len(self.cpu_ms)}), max {self.cpu_ms_max:.1f} ms "
                f"(update_load {self._load:g})")

    def close(self, timeout: float = 5.0) -> None:
        """Stop the thread (waits for a running call up to ``timeout``)."""
        self._closed.set()
        self._wake.set()
        if self._slots is not None:
            self._slots.close()
        self._thread.join(timeout)
