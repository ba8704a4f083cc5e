"""A lock-step member's side: the inputs it receives, held by stamp until the tick they belong
to (:class:`Inbox`), and what a tick still waits for.

At tick ``k`` (sim time ``t_k``, the tick before ``t_{k-1}``) a robot uses exactly:

* its pose stamped ``t_k``;
* its scans stamped in ``(t_{k-1}, t_k]`` when the tick lists it among the robots that scanned;
* the coverage state stamped ``t_{k-1}`` of every robot the tick lists as ``answered`` (those
  that answered tick ``k - 1``, itself excepted);
* exploring, every neighbour's evidence stamped up to ``t_{k-1}``: a state names the stamp of
  its sender's newest evidence message (:data:`EVIDENCE_KEY`), which must have arrived.

Messages may arrive in any order and early (a neighbour one tick ahead); nothing newer than the
tick is handed out, so what a robot computes depends on the tick alone. Thread-safe: messages
come from the executor thread, ticks are worked on another.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

#: The coverage_state value naming the sender's newest evidence message stamp [s] (exploring).
EVIDENCE_KEY = "evidence_stamp"
#: Poses and scans older than the tick being worked on by more than this are dropped [ns].
KEEP = 2_000_000_000


def ticks_per(period: float, tick: float) -> int:
    """How many ticks of ``tick`` [s] make ``period`` [s] (at least one): a rate's schedule."""
    return max(1, round(period / tick)) if tick > 0 else 1


@dataclass(frozen=True)
class Tick:
    """One ``coverage_msgs/LockstepTick``; stamps in integer nanoseconds of sim time."""

    index: int
    stamp: int
    previous: int
    period: float  # [s]
    robots: frozenset[int] = frozenset()
    observers: frozenset[str] = frozenset()
    answered: tuple[int, ...] = ()
    scanned: frozenset[int] = frozenset()
    status: bool = False

    @property
    def time(self) -> float:
        """[s] sim time of the tick."""
        return self.stamp * 1e-9

    def due(self, every: int, offset: int = 1) -> bool:
        """Whether something done every ``every`` ticks, first at tick ``offset``, is due."""
        return self.index >= offset and (self.index - offset) % every == 0


@dataclass
class TickInputs:
    """What one tick hands out (see module docstring)."""

    pose: Any = None
    scans: list[tuple[int, Any]] = field(default_factory=list)  # (stamp, scan), oldest first
    states: dict[int, dict[str, float]] = field(default_factory=dict)  # by robot id
    evidence: list[tuple[int, int, Any]] = field(default_factory=list)  # (sender, stamp, e)


class Inbox:
    """Stamped inputs of one member (robot ``own_id``, or -1 for an observer)."""

    def __init__(self, own_id: int = -1) -> None:
        self.own_id = own_id
        self._lock = threading.Lock()
        self._poses: dict[int, Any] = {}
        self._scans: list[tuple[int, Any]] = []
        self._states: dict[int, dict[int, dict[str, float]]] = {}
        self._evidence: dict[int, dict[int, Any]] = {}
        self._merged: dict[int, int] = {}  # sender -> newest evidence stamp handed out

    # ------------------------------------------------------------------ messages
    def put_pose(self, stamp: int, pose: Any) -> None:
        with self._lock:
            self._poses[stamp] = pose

    def put_scan(self, stamp: int, scan: Any) -> None:
        with self._lock:
            self._scans.append((stamp, scan))

    def put_state(self, sender: int, stamp: int, values: dict[str, float]) -> None:
        if sender == self.own_id:
            return
        with self._lock:
            self._states.setdefault(sender, {})[stamp] = values

    def put_evidence(self, sender: int, stamp: int, evidence: Any) -> None:
        if sender == self.own_id:
            return
        with self._lock:
            if stamp > self._merged.get(sender, -1):
                self._evidence.setdefault(sender, {})[stamp] = evidence

    # ------------------------------------------------------------------ ticks
    def _due_states(self, tick: Tick) -> list[int]:
        return [r for r in tick.answered if r != self.own_id]

    def missing(self, tick: Tick, pose: bool = True, scan: bool = False, states: bool = True,
                evidence: bool = False) -> list[str]:
        """What ``tick`` still waits for (empty: ready), e.g. ``["pose", "state of robot 3"]``.
        ``scan``: this member uses its lidar; ``evidence``: it merges its neighbours'."""
        out = []
        with self._lock:
            if pose and tick.stamp not in self._poses:
                out.append("pose")
            if scan and self.own_id in tick.scanned and not any(
                    tick.previous < s <= tick.stamp for s, _ in self._scans):
                out.append("scan")
            if not states:
                return out
            for rid in self._due_states(tick):
                values = self._states.get(rid, {}).get(tick.previous)
                if values is None:
                    out.append(f"state of robot {rid}")
                    continue
                if not evidence:
                    continue
                wanted = evidence_stamp(values)
                if wanted is not None and wanted > self._merged.get(rid, -1) and \
                        wanted not in self._evidence.get(rid, {}):
                    out.append(f"evidence of robot {rid}")
        return out

    def take(self, tick: Tick, evidence: bool = False) -> TickInputs:
        """Hand out the inputs of ``tick`` (whatever of them arrived) and forget older ones."""
        with self._lock:
            got = TickInputs(pose=self._poses.get(tick.stamp))
            self._poses = {s: p for s, p in self._poses.items() if s > tick.stamp}
            keep = []
            for s, scan in sorted(self._scans, key=lambda item: item[0]):
                if s <= tick.stamp:
                    if s > tick.stamp - KEEP:
                        got.scans.append((s, scan))
                else:
                    keep.append((s, scan))
            self._scans = keep
            for rid in self._due_states(tick):
                values = self._states.get(rid, {}).get(tick.previous)
                if values is not None:
                    got.states[rid] = values
            for rid in list(self._states):  # (those of this tick are due at the next)
                newer = {s: v for s, v in self._states[rid].items() if s >= tick.stamp}
                if newer:
                    self._states[rid] = newer
                else:
                    del self._states[rid]
            if evidence:
                for rid in sorted(self._evidence):
                    items = self._evidence[rid]
                    for s in sorted(x for x in items if x <= tick.previous):
                        got.evidence.append((rid, s, items.pop(s)))
                        self._merged[rid] = s
        return got


def evidence_stamp(values: dict[str, float]) -> int | None:
    """The sender's newest evidence stamp [ns] named by a state, or None."""
    v = values.get(EVIDENCE_KEY)
    if v is None or not v >= 0:
        return None
    return round(v * 1e9)
