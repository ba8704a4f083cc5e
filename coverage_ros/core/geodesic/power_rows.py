"""Whole-domain searches of power cells, one per generator, kept in their domain by source.

A power cell (unequal weights) over the whole domain needs every generator's own unlimited
search (:func:`coverage_ros.core.geodesic.cell.geodesic_cell`); a search from one generator
depends on that generator's source edges alone, not on the others. Robots that share a domain
(an exploring team in one process, whose domain is made once per belief version; a
``robot_container``) and hear the same generator there search from it once: the rows are kept
in the domain under the source's nodes and costs, so only the very same source reuses a row.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain, Snap

__all__ = ["whole_power_rows"]

#: [bytes] kept rows of one domain at most (the oldest go first)
KEPT_BYTES = 64 << 20
#: predecessor marking "the row's own source" in a kept row (-9999 is scipy's "none")
FROM_SOURCE = -1

#: kept rows by (method, source nodes, source costs): distances and predecessors of sink and nodes
Kept = dict[tuple[str, bytes, bytes], tuple[np.ndarray, np.ndarray]]


def whole_power_rows(domain: CoverageDomain, csr: csr_matrix, snaps: Sequence[Snap],
                     method: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per generator ``k`` (its source is row ``first + k`` of ``csr``, the whole-domain
    search graph with one source per snap appended after its ``first`` rows: sink and nodes),
    the distances and predecessors of the unlimited search from it over all of ``csr``'s rows,
    as :func:`scipy.sparse.csgraph.dijkstra` gives them from that source alone."""
    size = csr.shape[0]
    first = size - len(snaps)
    kept: Kept = domain._cache.setdefault("power_rows", {})
    rows = []
    for k, snap in enumerate(snaps):
        key = (method, np.asarray(snap[0]).tobytes(), np.asarray(snap[1]).tobytes())
        row = kept.get(key)
        if row is None or len(row[0]) != first:
            d, p = dijkstra(csr, directed=True, indices=first + k, return_predecessors=True)
            own = np.where(p[:first] >= first, FROM_SOURCE, p[:first]).astype(np.int32)
            row = (d[:first].copy(), own)
            kept.pop(key, None)
            kept[key] = row
            _trim(kept)
        d_k = np.full(size, np.inf)
        d_k[:first] = row[0]
        d_k[first + k] = 0.0
        p_k = np.full(size, -9999, dtype=np.int32)
        p_k[:first] = np.where(row[1] == FROM_SOURCE, first + k, row[1])
        rows.append((d_k, p_k))
    return rows


def _trim(kept: Kept) -> None:
    """Drop the oldest rows (dicts keep insertion order) until the rest fit KEPT_BYTES; the
    newest always stays."""
    total = sum(d.nbytes + p.nbytes for d, p in list(kept.values()))
    while total > KEPT_BYTES and len(kept) > 1:
        d, p = kept.pop(next(iter(kept)))
        total -= d.nbytes + p.nbytes
