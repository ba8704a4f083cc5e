"""The work of the geodesic searches a robot's update runs, counted without changing its code
(Bhattacharya et al.'s Fig. 13 counts the vertices its search expands): the vertices scipy's
Dijkstra settles and the cells tested for line of sight (:func:`counting_searches`).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csgraph

from coverage_ros.core.geodesic import cell as cell_module
from coverage_ros.core.geodesic import shared_search as shared_search_module
from coverage_ros.core.geodesic import tessellation as tessellation_module
from coverage_ros.core.geodesic import visible_first as visible_first_module
from coverage_ros.core.geodesic.domain import CoverageDomain
from coverage_ros.errors import ConfigError


@dataclass
class SearchCount:
    """Work of the geodesic searches run inside :func:`counting_searches`."""

    settled: int = 0  # nodes taken off scipy Dijkstra's heap (finite distance), sources excluded
    sighted: int = 0  # cells tested for line of sight (visibility sources, visible-first search),
    # one by one or a tile at a time (the free cells of every tile decided)


#: The modules whose searches are counted (each imports scipy's ``dijkstra`` by name).
_SEARCH_MODULES = (cell_module, shared_search_module, tessellation_module,
                   visible_first_module)


@contextmanager
def counting_searches() -> Iterator[SearchCount]:
    """Count, inside the block, every vertex the geodesic searches settle: scipy's Dijkstra
    settles exactly the nodes it returns a finite distance for (a node beyond ``limit`` is never
    pushed), so each call adds its finite distances less its virtual sources; and every cell a
    line-of-sight test looks at, one by one or a tile at a time. The robots' own code runs
    unchanged: the counting wrappers are put in place of ``dijkstra`` and
    ``CoverageDomain.visible_mask``, ``visible_each`` and ``sight_tiles_whole`` for the block only
    (this process only; not thread-safe)."""
    count = SearchCount()
    scipy_dijkstra = csgraph.dijkstra
    plain_mask = CoverageDomain.visible_mask
    plain_each = CoverageDomain.visible_each
    plain_tiles = CoverageDomain.sight_tiles_whole
    # What the class itself holds (the methods come from its base, LineOfSight): put back as
    # it was, so that nothing is left shadowing the base's methods after the block.
    own = {name: CoverageDomain.__dict__.get(name)
           for name in ("visible_mask", "visible_each", "sight_tiles_whole")}

    def dijkstra(graph, *args, **kwargs):
        if "indices" not in kwargs:
            raise ConfigError.at("counting_searches", "a search without keyword 'indices'",
                                 args, "dijkstra(graph, indices=...)")
        out = scipy_dijkstra(graph, *args, **kwargs)
        dist = out[0] if isinstance(out, tuple) else out
        count.settled += int(np.count_nonzero(np.isfinite(dist))) - int(
            np.size(kwargs["indices"]))
        return out

    def visible_mask(self, origin, points, radius, depths=None, point_tiles=None):
        count.sighted += len(points)
        return plain_mask(self, origin, points, radius, depths, point_tiles)

    def visible_each(self, origin, points, depths):
        count.sighted += len(points)
        return plain_each(self, origin, points, depths)

    def sight_tiles_whole(self, origin, depths):
        count.sighted += int(np.count_nonzero(self.free))  # (every tile decided or not)
        return plain_tiles(self, origin, depths)

    for module in _SEARCH_MODULES:
        if module.dijkstra is not scipy_dijkstra:
            raise ConfigError.at(module.__name__, "dijkstra is not scipy's (nested counting?)")
    # (replaced in place on purpose: the robots' code runs unchanged)
    try:
        for module in _SEARCH_MODULES:
            module.dijkstra = dijkstra  # type: ignore[attr-defined]
        CoverageDomain.visible_mask = visible_mask  # type: ignore[method-assign]
        CoverageDomain.visible_each = visible_each  # type: ignore[method-assign]
        CoverageDomain.sight_tiles_whole = sight_tiles_whole  # type: ignore[method-assign]
        yield count
    finally:
        for module in _SEARCH_MODULES:
            module.dijkstra = scipy_dijkstra  # type: ignore[attr-defined]
        for name, method in own.items():
            if method is None:
                delattr(CoverageDomain, name)
            else:
                setattr(CoverageDomain, name, method)
