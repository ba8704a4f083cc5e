"""Searches over the whole map from points: the nearest of several (:func:`nearest`), a cell's
cost about another point (:func:`cell_cost_about`), and the virtual sources' edges they start
from, kept per point for every such search on a domain (:func:`source_rows`).

A source's row (:func:`~coverage_ros.core.geodesic.tessellation.source_row`) joins a point to
its snap cells and, with ``visibility`` sources, to every free cell in line of sight within
the search radius. Whether a cell is in sight does not depend on the radius, so the row of a
smaller radius is the row of a larger one without the cells beyond it: one row per point,
searched to the largest radius asked so far, serves every search from that point. Bounds
that price many moves ask for the same points many times (generators that stay put, Lloyd
steps that come back to a node), at several radii.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.core.geodesic.local_search import LocalGraph, local_graph_for
from coverage_ros.core.geodesic.tessellation import resolve_method, source_row_with_reach

#: Entries (edges) kept over all points of one domain, least recently used dropped first:
#: 20 bytes each, so at most about 20 MB (the escape's bounds on the office at 5 cm, six
#: robots, make 12 % more rows with this than with four times as many, 77 % more with a
#: quarter as many).
CAPACITY = 1_000_000


@dataclass(frozen=True)
class _Row:
    radius: float  # [chart units] the search radius it was made for
    lids: np.ndarray  # (k,) local ids of the whole-map graph
    costs: np.ndarray  # (k,) edge costs [chart units]
    d2: np.ndarray  # (k,) [cells^2] squared distance of a line-of-sight edge; -1: a snap edge


class SourceRows:
    """Rows of one domain's whole-map graph by map-frame point (not thread-safe)."""

    def __init__(self, domain: CoverageDomain, method: str,
                 capacity: int = CAPACITY) -> None:
        self.domain = domain
        self.method = resolve_method(domain, method)
        self.local: LocalGraph = local_graph_for(domain, None, np.zeros((1, 2)), np.zeros(1),
                                                 math.inf)
        self.capacity = capacity
        self._rows: OrderedDict[tuple[float, float], _Row] = OrderedDict()
        self._size = 0
        self.made = 0  # rows computed (a point asked again at a larger radius counts again)

    def row(self, point: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Local ids and costs of the edges of a source at ``point`` (2,) [m] for a search
        up to ``radius`` (chart units; inf: the whole map)."""
        key = (float(point[0]), float(point[1]))
        row = self._rows.get(key)
        if row is None or row.radius < radius:
            if row is not None:  # (made again: it goes last, as a new row does)
                del self._rows[key]
                self._size -= len(row.lids)
            lids, costs, d2 = source_row_with_reach(self.domain, self.local,
                                                    self.domain.snap(np.asarray(point)),
                                                    radius, self.method)
            row = _Row(float(radius), lids.astype(np.int32), costs, d2)
            self.made += 1
            self._rows[key] = row
            self._size += len(lids)
            while self._size > self.capacity and len(self._rows) > 1:
                _, old = self._rows.popitem(last=False)  # (never the newest: it is last)
                self._size -= len(old.lids)
        else:
            self._rows.move_to_end(key)
        if row.radius == radius or self.method != "visibility":
            return row.lids, row.costs
        r_cells = radius / self.domain.resolution
        keep = row.d2 <= r_cells * r_cells
        return row.lids[keep], row.costs[keep]


def source_rows(domain: CoverageDomain, method: str = "auto") -> SourceRows:
    """The domain's one :class:`SourceRows` for ``method`` (made on first use)."""
    key = ("source_rows", resolve_method(domain, method))
    rows = domain._cache.get(key)
    if rows is None:
        rows = SourceRows(domain, method)
        domain._cache[key] = rows
    assert isinstance(rows, SourceRows)
    return rows


def nearest(domain: CoverageDomain, points: np.ndarray, limit: float,
            method: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """``(H * W,)`` geodesic distance (chart units) of every node from the nearest of
    ``points (m, 2)`` [m] and that point's index, searched up to ``limit`` (inf and -1
    beyond). Read-only arrays, kept in the domain for the same points and limit (the bounds
    ask again for half of theirs: generators that stay, Lloyd steps that come back)."""
    rows = source_rows(domain, method)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    memo = _nearest_memo(domain)
    key = (rows.method, float(limit), pts.tobytes())
    found = memo.get(key)
    if found is not None:
        memo.move_to_end(key)
        return found
    csr = rows.local.with_sources([rows.row(p, limit) for p in pts])
    n = rows.local.n
    d, _, src = dijkstra(csr, directed=True, indices=np.arange(n + 1, n + 1 + len(pts)),
                         limit=limit, min_only=True, return_predecessors=True)
    label = np.where(src >= 0, src - (n + 1), -1)
    out = (d[1:n + 1], label[1:n + 1])  # whole-graph local ids are node ids + 1
    for a in out:
        a.flags.writeable = False
    memo[key] = out
    while len(memo) > max(1, NEAREST_MEMO_BYTES // max(16 * n, 1)):
        memo.popitem(last=False)
    return out


#: [bytes] searches :func:`nearest` keeps per domain (16 bytes a node each), least recently
#: used dropped first
NEAREST_MEMO_BYTES = 64 << 20


def _nearest_memo(domain: CoverageDomain
                  ) -> OrderedDict[tuple[str, float, bytes], tuple[np.ndarray, np.ndarray]]:
    memo = domain._cache.get("nearest_memo")
    if memo is None:
        memo = domain._cache["nearest_memo"] = OrderedDict()
    assert isinstance(memo, OrderedDict)
    return memo


def cell_cost_about(domain: CoverageDomain, nodes: np.ndarray, point: np.ndarray,
                    weight: float, limit: float, method: str = "auto") -> float:
    """Coverage cost sum (g^2 - R^2) w dA of the fixed cell ``nodes`` about another position
    ``point`` (2,) [m]: geodesic distances g from it, with the tessellation's sources, searched
    up to ``limit``; inf if a node of the cell lies beyond."""
    rows = source_rows(domain, method)
    csr = rows.local.with_sources([rows.row(np.asarray(point, dtype=np.float64), limit)])
    d = dijkstra(csr, directed=True, indices=rows.local.n + 1, limit=limit)
    g = d[nodes + 1]  # whole-graph local ids are node ids + 1
    if not np.all(np.isfinite(g)):
        return math.inf
    return float(((g * g - weight ** 2) * domain.mass_element.ravel()[nodes]).sum())
