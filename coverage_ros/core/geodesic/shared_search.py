"""Whole-map searches kept in their domain and shared by the robots that use it.

A robot whose cell is most of the map searches the whole domain at once (one multi-source
Dijkstra with equal weights, or :func:`.visible_first.visible_first_search`), which gives every
generator's cell, not only its own. The domain keeps the latest such search with the
generator positions it was made from (``domain._cache["shared_search"]``), so that:

* robots that see the very same generators (an offline team step, an exploring team in one
  process) search once;
* a robot of a ``robot_container`` (which shares one domain among its robots) takes its cell
  from a search another robot made since its own last update when each generator of its view
  is within ``reuse`` of one of that search's, one to one (robot_node ``search_reuse``): the
  exact cell of a team that near. It never takes its own search, nor one it has steered by.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import dijkstra

from coverage_ros.core.geodesic.domain import CoverageDomain, Snap
from coverage_ros.core.geodesic.local_search import LocalGraph, local_graph_for
from coverage_ros.core.geodesic.tessellation import Generator, source_row
from coverage_ros.core.geodesic.visible_first import visible_first_search

__all__ = ["held_search", "shared_search", "whole_search"]

#: A robot's cell in a whole-map search: ``(graph, (own, g, pred, touching), base node, grid
#: point)`` (:func:`held_search`).
HeldCell = tuple[LocalGraph, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], int,
                 np.ndarray]


@dataclass(frozen=True)
class _WholeSearch:
    """A whole-map multi-source search kept in its domain (the latest one)."""

    method: str
    positions: np.ndarray  # (k, 2) [m] the generators, in source order
    grids: np.ndarray  # (k, 2) their grid coordinates
    bases: np.ndarray  # (k,) the node each one's snap starts from
    dist: np.ndarray
    pred: np.ndarray
    label: np.ndarray  # source order, -1 for nobody's


def shared_search(domain: CoverageDomain, local: LocalGraph, gens: Sequence[Generator],
                  snaps: list[Snap], method: str, reuse: float = 0.0, last: object = None
                  ) -> HeldCell:
    """The search of ``cell._search`` over the whole domain with equal weights, for generator
    0, from one multi-source Dijkstra kept in the domain: robots that share a domain and see
    the same generators, or ones within ``reuse`` of them (a team in one process), search it
    once. The sources are ordered by position, so every robot's search is the same one.
    Returns what :func:`held_search` does."""
    held = held_search(domain, gens, method, reuse, last)
    if held is not None:
        return held
    search, match = whole_search(domain, local, gens, snaps, method)
    return _cell_in(search, local, match)


def whole_search(domain: CoverageDomain, local: LocalGraph, gens: Sequence[Generator],
                 snaps: list[Snap], method: str) -> tuple[_WholeSearch, np.ndarray]:
    """The whole-domain multi-source search of ``gens`` (equal weights) on the whole-domain
    graph ``local``, kept in the domain as its latest, and ``match``: ``gens[k]`` is its
    source ``match[k]`` (sources ordered by position, so that every robot's search is the
    same one)."""
    order = sorted(range(len(gens)), key=lambda k: (float(gens[k].position[0]),
                                                    float(gens[k].position[1])))
    first = local.n + 1
    if method == "visibility" and local.covers_all:
        dist, pred, label = visible_first_search(domain, local, [snaps[k] for k in order])
    else:
        csr = local.with_sources([source_row(domain, local, snaps[k], math.inf, method)
                                  for k in order])
        dist, pred, src = dijkstra(csr, directed=True,
                                   indices=np.arange(first, first + len(gens)),
                                   min_only=True, return_predecessors=True)
        label = np.where(src >= 0, src - first, -1)
        label[0] = -1
    # One search kept (the latest): a team solver makes a new one every step.
    search = _WholeSearch(
        method, np.array([gens[k].position for k in order], dtype=np.float64),
        np.array([snaps[k][2] for k in order]),
        np.array([int(snaps[k][0][0]) for k in order], dtype=np.int64), dist, pred, label)
    domain._cache["shared_search"] = search
    match = np.empty(len(gens), dtype=np.int64)
    match[order] = np.arange(len(gens))  # (not matched by position: two may share one)
    return search, match


def held_search(domain: CoverageDomain, gens: Sequence[Generator], method: str,
                reuse: float, last: object = None) -> HeldCell | None:
    """The own cell (generator 0) in the domain's kept whole-map search when every one of
    ``gens`` is within ``reuse`` [m] of its nearest generator there, no two the same one
    (``reuse`` 0: at the same point), and unless it is ``last`` (the one kept when the robot's
    last update ended) and some are not at the same point: a robot takes an approximate search
    only from a sibling, made since its own last update - it never steers twice by the same
    one, and a robot alone in its domain never by one at all; None otherwise. Returns
    ``(local, (own, g, pred, touching), base node, grid point)``: the whole-domain graph,
    what ``cell._search`` returns (touching: indices into ``gens``) and the own generator's
    snap there."""
    held = domain._cache.get("shared_search")
    if held is None or held.method != method or len(held.positions) != len(gens):
        return None
    want = np.array([g.position for g in gens], dtype=np.float64)
    gap = np.hypot(want[:, None, 0] - held.positions[None, :, 0],
                   want[:, None, 1] - held.positions[None, :, 1])
    match = np.argmin(gap, axis=1)
    worst = gap[np.arange(len(gens)), match].max()
    if worst > reuse or len(np.unique(match)) < len(gens) or (held is last and worst > 0):
        return None
    return _cell_in(held, local_graph_for(domain, None, held.grids[:1], np.zeros(1), math.inf),
                    match)


def _cell_in(held: _WholeSearch, local: LocalGraph, match: np.ndarray) -> HeldCell:
    """:func:`held_search`'s result for the generators whose sources in ``held`` are
    ``match`` (``gens[k]`` is source ``match[k]``) on the whole-domain graph ``local``."""
    own_label = int(match[0])
    own = np.flatnonzero(held.label[1:local.n + 1] == own_label) + 1
    nb_label = held.label[local.nb[own - 1]]
    touching_held = np.unique(nb_label[local.edge[own - 1] & (nb_label >= 0)
                                       & (nb_label != own_label)])
    back = np.empty(len(match), dtype=np.int64)
    back[match] = np.arange(len(match))
    return (local, (own, held.dist[own], held.pred, back[touching_held]),
            int(held.bases[own_label]), held.grids[own_label])
