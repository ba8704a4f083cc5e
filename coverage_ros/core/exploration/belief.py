"""What a robot believes of an unknown map, and how a team's beliefs are fused without a map
server (:class:`Belief`).

Evidence, not probabilities, is what robots keep and exchange: for every cell of the lattice
and every robot (a *source*) the number of times that robot's lidar saw the cell occupied
(``hits``) and free (``misses``). The occupancy log-odds of a cell is ::

    L = l_occ * sum_sources hits + l_free * sum_sources misses,   clamped to [-L_max, L_max]

(prior p = 0.5, L = 0), and p = 1 / (1 + exp(-L)). Counts add, so fusing two robots' evidence
gives exactly what one robot seeing both scan sequences would have. A robot's own counts only
grow, so the counts it publishes are a grow-only state: a receiver keeps, per source and cell,
the largest count it has heard (:meth:`Belief.merge`). Merging is therefore idempotent (a
repeated or re-sent message changes nothing: no double counting), commutative and
order-independent (out-of-order delivery is harmless), and a lost message is repaired by any
later one that carries the cell - every robot re-sends all its evidence, a bounded chunk at a
time (:meth:`Belief.refresh_chunk`), which is also how a late-joining robot catches up.

Obstacle edges: a cell that holds the edge or corner of an obstacle is crossed by some beams and
ends others, so its log-odds can hover near 0 however often it is seen - a cell that stays
"unexplored" forever, and pulls the whole team to it (the entropy-weighted density). A cell seen
at least ``edge_after`` times of which at least ``edge_share`` were returns is therefore decided
occupied (L = +L_max). With the defaults (12, 1/4) every cell seen 12 times is decided one way or
the other (below a quarter of returns the log-odds is already at most -1.5, p < 0.19), and the
rule leans to occupied at the margin (the log-odds alone would switch at a share of 0.32), the
safe side for navigation.

A robot's own footprint: where a robot stands there is no wall, whatever lidars saw there. A
teammate's lidar that saw the robot's body before it heard the robot's state (a team starting in
a cluster sees itself for seconds before discovery) marks the body's edge occupied, often
enough to freeze it - a ring the robot could then never leave, its clearance to the ring below
the configuration space's. So each robot counts its footprint (:meth:`Belief.add_footprint`)
as ``FOOTPRINT_MISSES`` misses of its own, past any freeze: more than the returns a whole team
puts in a cell before it freezes, so the cells are free in every belief the evidence reaches.

Cells whose belief entropy has dropped below ``frozen_entropy`` (tau' of Bhattacharya et al.)
are frozen: the robot's own scans no longer count there, so a decided cell stops generating
traffic and the belief of an explored map stops changing.

Thread safety: scans and neighbours' evidence arrive on one thread while strategies read the
belief on another; every method takes the belief's lock, and :meth:`snapshot` returns copies.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Hashable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from coverage_ros.core.exploration.sensor_model import ScanCells
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError

#: Largest count kept per source, cell and kind (uint16 storage).
COUNT_MAX = 65535
#: Misses a robot counts for each cell of its own footprint (see module docstring). A cell
#: freezes after about ``edge_after`` observations, so a team of n robots puts at most about
#: 12 n returns there; the edge rule needs returns >= 1/4 of all observations, so 1000 misses
#: clear a cell for any team below ~300 robots.
FOOTPRINT_MISSES = 1000


@dataclass(frozen=True)
class BeliefConfig:
    """The inverse sensor model's log-odds and the belief's limits."""

    p_hit: float = 0.7  # P(occupied | a return in the cell)
    p_miss: float = 0.4  # P(occupied | a beam crossed the cell)
    p_max: float = 0.97  # beliefs are clamped to [1 - p_max, p_max]
    frozen_entropy: float = 0.2  # [nats] tau': cells below this entropy are frozen
    edge_after: int = 12  # a cell seen this often with >= edge_share returns is occupied
    edge_share: float = 0.25

    def __post_init__(self) -> None:
        if not 0.5 < self.p_hit < 1.0:
            raise ConfigError.at("p_hit", "must be in (0.5, 1)", self.p_hit)
        if not 0.0 < self.p_miss < 0.5:
            raise ConfigError.at("p_miss", "must be in (0, 0.5)", self.p_miss)
        if not 0.5 < self.p_max < 1.0:
            raise ConfigError.at("p_max", "must be in (0.5, 1)", self.p_max)
        if not 0.0 <= self.frozen_entropy < math.log(2.0):
            raise ConfigError.at("frozen_entropy", "must be in [0, ln 2) nats",
                                 self.frozen_entropy)
        if not (isinstance(self.edge_after, int) and self.edge_after >= 1):
            raise ConfigError.at("edge_after", "must be an integer >= 1 [observations]",
                                 self.edge_after)
        if not 0.0 < self.edge_share <= 1.0:
            raise ConfigError.at("edge_share", "must be in (0, 1]", self.edge_share)

    @property
    def l_occ(self) -> float:
        return math.log(self.p_hit / (1.0 - self.p_hit))

    @property
    def l_free(self) -> float:
        return math.log(self.p_miss / (1.0 - self.p_miss))

    @property
    def l_max(self) -> float:
        return math.log(self.p_max / (1.0 - self.p_max))

    @property
    def frozen_log_odds(self) -> float:
        """|L| above which the entropy is below ``frozen_entropy`` (inf if it never is)."""
        if self.frozen_entropy <= 0:
            return math.inf
        # e(p) is decreasing in p on [0.5, 1): bisect e(p) = tau'.
        lo, hi = 0.5, 1.0 - 1e-12
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if entropy(np.array(mid)) > self.frozen_entropy:
                lo = mid
            else:
                hi = mid
        return math.log(hi / (1.0 - hi))


def entropy(p: np.ndarray) -> np.ndarray:
    """Shannon entropy [nats] of occupancy probabilities: -(p ln p + (1 - p) ln(1 - p)); ln 2 at
    p = 0.5, 0 at p = 0 or 1."""
    p = np.clip(np.asarray(p, dtype=np.float64), 1e-12, 1.0 - 1e-12)
    h: np.ndarray = -(p * np.log(p) + (1.0 - p) * np.log(1.0 - p))
    return h


@dataclass(frozen=True)
class Evidence:
    """Some cells of one source's evidence: flat indices and their counts (all ``(n,)``)."""

    source: int
    cells: np.ndarray  # int64 flat lattice indices
    hits: np.ndarray  # uint16
    misses: np.ndarray  # uint16


def joined(*parts: Evidence) -> Evidence:
    """Several pieces of one source's evidence as one (a cell in two holds the same counts)."""
    return Evidence(parts[0].source, np.concatenate([p.cells for p in parts]),
                    np.concatenate([p.hits for p in parts]),
                    np.concatenate([p.misses for p in parts]))


@dataclass(frozen=True, eq=False)
class BeliefSnapshot:
    """A copy of a belief at one moment (what a strategy plans on). Maps derived from it
    (navigation and entropy domains) are memoized in ``derived``, so robots that share one
    belief (the offline runner) build them once."""

    lattice: GridMap
    log_odds: np.ndarray  # (H, W) float32
    observed: np.ndarray  # (H, W) bool: any evidence at all
    config: BeliefConfig
    version: int = 0  # the belief's change count when the snapshot was taken
    derived: dict[Hashable, Any] = field(default_factory=dict, repr=False)

    @property
    def probability(self) -> np.ndarray:
        """``(H, W)`` occupancy probability (0.5 where nothing was seen)."""
        return 1.0 / (1.0 + np.exp(-self.log_odds.astype(np.float64)))

    @property
    def entropy(self) -> np.ndarray:
        return entropy(self.probability)


class Belief:
    """One robot's occupancy belief over a known lattice (see module docstring)."""

    def __init__(self, lattice: GridMap, own_id: int, config: BeliefConfig | None = None) -> None:
        self.lattice = GridMap(np.full(lattice.shape, -1, np.int8), lattice.resolution,
                               lattice.origin)
        self.own_id = int(own_id)
        self.config = config or BeliefConfig()
        n = self.lattice.width * self.lattice.height
        self._n = n
        self._hits = np.zeros(n, np.int64)  # totals over sources
        self._misses = np.zeros(n, np.int64)
        self._sources: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._dirty = np.zeros(n, bool)  # own cells changed since the last take_changes
        self._refresh_at = 0  # round-robin position of refresh_chunk
        self._version = 0  # changes so far
        self._snapshot: BeliefSnapshot | None = None
        self._lock = threading.Lock()
        self._source(self.own_id)

    # ------------------------------------------------------------------ evidence in
    def _source(self, source: int) -> tuple[np.ndarray, np.ndarray]:
        counts = self._sources.get(source)
        if counts is None:
            counts = (np.zeros(self._n, np.uint16), np.zeros(self._n, np.uint16))
            self._sources[source] = counts
        return counts

    def add_scan(self, cells: ScanCells) -> int:
        """Count one own scan (cells frozen already are skipped); how many cells changed."""
        with self._lock:
            hits, misses = self._source(self.own_id)
            changed = 0
            for idx, own, total in ((cells.occupied, hits, self._hits),
                                    (cells.free, misses, self._misses)):
                idx = idx[~self._frozen(idx)]
                idx = idx[own[idx] < COUNT_MAX]
                own[idx] += 1
                total[idx] += 1
                self._dirty[idx] = True
                changed += len(idx)
            self._version += bool(changed)
            return changed

    def add_footprint(self, cells: np.ndarray) -> int:
        """The cells under this robot's body (``footprint_cells``): free, as at least
        ``FOOTPRINT_MISSES`` own misses each, frozen or not (see module docstring); how many
        cells changed."""
        idx = np.asarray(cells, np.int64).ravel()
        idx = idx[(idx >= 0) & (idx < self._n)]
        with self._lock:
            _, misses = self._source(self.own_id)
            idx = idx[misses[idx] < FOOTPRINT_MISSES]
            self._misses[idx] += FOOTPRINT_MISSES - misses[idx].astype(np.int64)
            misses[idx] = FOOTPRINT_MISSES
            self._dirty[idx] = True
            self._version += bool(len(idx))
            return len(idx)

    def merge(self, evidence: Evidence) -> int:
        """Take another robot's evidence (a grow-only state: per cell, the largest count heard
        wins); how many cells changed. Evidence of this robot itself is ignored."""
        if evidence.source == self.own_id:
            return 0
        cells = np.asarray(evidence.cells, np.int64).ravel()
        ok = (cells >= 0) & (cells < self._n)
        cells = cells[ok]
        with self._lock:
            hits, misses = self._source(evidence.source)
            grown: list[np.ndarray] = []
            for got, mine, total in ((evidence.hits, hits, self._hits),
                                     (evidence.misses, misses, self._misses)):
                got = np.minimum(np.asarray(got, np.int64).ravel()[ok], COUNT_MAX)
                # One count per cell: the largest (a message may repeat a cell).
                order = np.lexsort((got, cells))
                c, g = cells[order], got[order]
                last = np.append(c[1:] != c[:-1], True) if len(c) else np.zeros(0, bool)
                c, g = c[last], g[last]
                old = mine[c].astype(np.int64)
                grow = g > old
                total[c[grow]] += g[grow] - old[grow]
                mine[c[grow]] = g[grow]
                grown.append(c[grow])
            changed = len(np.union1d(*grown))
            self._version += bool(changed)
            return changed

    # ------------------------------------------------------------------ evidence out
    def take_changes(self, max_cells: int) -> Evidence | None:
        """The own evidence at up to ``max_cells`` cells changed since they were last taken
        (None if nothing changed)."""
        with self._lock:
            dirty = np.flatnonzero(self._dirty)[:max_cells]
            if len(dirty) == 0:
                return None
            self._dirty[dirty] = False
            return self._own_evidence(dirty)

    def refresh_chunk(self, max_cells: int) -> Evidence | None:
        """The next ``max_cells`` cells (round robin) of all the own evidence, for repair and
        late joiners (None if there is none)."""
        with self._lock:
            hits, misses = self._sources[self.own_id]
            seen = np.flatnonzero((hits > 0) | (misses > 0))
            if len(seen) == 0:
                return None
            start = int(np.searchsorted(seen, self._refresh_at))
            if start >= len(seen):
                start = 0
            chunk = seen[start:start + max_cells]
            self._refresh_at = int(chunk[-1]) + 1
            return self._own_evidence(chunk)

    def _own_evidence(self, cells: np.ndarray) -> Evidence:
        hits, misses = self._sources[self.own_id]
        return Evidence(self.own_id, cells.astype(np.int64), hits[cells].copy(),
                        misses[cells].copy())

    # ------------------------------------------------------------------ reading
    def _log_odds(self, idx: np.ndarray | slice) -> np.ndarray:
        c = self.config
        hits, misses = self._hits[idx], self._misses[idx]
        lo = np.clip(c.l_occ * hits + c.l_free * misses, -c.l_max, c.l_max)
        seen = hits + misses
        edge = (seen >= c.edge_after) & (hits >= c.edge_share * seen)
        return np.where(edge, c.l_max, lo)

    def _frozen(self, idx: np.ndarray) -> np.ndarray:
        frozen: np.ndarray = np.abs(self._log_odds(idx)) >= self.config.frozen_log_odds
        return frozen

    @property
    def version(self) -> int:
        """How many times the belief changed (a snapshot of the same version is reused)."""
        return self._version

    def snapshot(self) -> BeliefSnapshot:
        with self._lock:
            if self._snapshot is not None and self._snapshot.version == self._version:
                return self._snapshot
            lo = self._log_odds(slice(None)).astype(np.float32)
            observed = (self._hits > 0) | (self._misses > 0)
            shape = self.lattice.shape
            lo, observed = lo.reshape(shape), observed.reshape(shape)
            lo.setflags(write=False)
            observed.setflags(write=False)
            self._snapshot = BeliefSnapshot(self.lattice, lo, observed, self.config,
                                            self._version)
            return self._snapshot

    def sources(self) -> list[int]:
        with self._lock:
            return sorted(self._sources)

    def occupancy_percent(self) -> np.ndarray:
        """``(H, W) int8`` as nav_msgs/OccupancyGrid carries it: -1 where nothing was seen,
        else round(100 p)."""
        snap = self.snapshot()
        out = np.rint(100.0 * snap.probability).astype(np.int8)
        out[~snap.observed] = -1
        return out
