"""The whole-graph CSR matrix against one built edge by edge from the cost table."""

from __future__ import annotations

import numpy as np
import pytest

from coverage_ros.core.geodesic.graph import build_grid_graph


def edge_by_edge(graph) -> tuple[list[list[int]], list[list[float]]]:
    """Each node's neighbours (ascending) and edge costs, from ``graph.cost`` cell by cell."""
    H, W = graph.shape
    cols: list[list[int]] = [[] for _ in range(H * W)]
    costs: list[list[float]] = [[] for _ in range(H * W)]
    for r in range(H):
        for c in range(W):
            out = []
            for k, (dr, dc) in enumerate(graph.offsets):
                rr, cc = r + int(dr), c + int(dc)
                if graph.wrap[0]:
                    rr %= H
                if graph.wrap[1]:
                    cc %= W
                if np.isfinite(graph.cost[r, c, k]):
                    assert 0 <= rr < H and 0 <= cc < W
                    out.append((rr * W + cc, float(graph.cost[r, c, k])))
            out.sort()
            cols[r * W + c] = [v for v, _ in out]
            costs[r * W + c] = [w for _, w in out]
    return cols, costs


@pytest.mark.parametrize("connectivity", [8, 16])
@pytest.mark.parametrize("weighted", [False, True])
@pytest.mark.parametrize("wrap", [(False, False), (True, False), (True, True)])
def test_the_csr_matrix_holds_every_edge_once_in_column_order(connectivity, weighted, wrap):
    rng = np.random.default_rng(connectivity + 3 * weighted + 7 * sum(wrap))
    free = rng.random((13, 17)) < 0.7
    zeta = rng.uniform(0.5, 2.0, free.shape) if weighted else None
    graph = build_grid_graph(free, 0.1, connectivity=connectivity, zeta=zeta, wrap=wrap)
    csr = graph.csr
    cols, costs = edge_by_edge(graph)
    assert csr.shape == (free.size, free.size)
    assert csr.nnz == sum(len(c) for c in cols) > 0
    for node in range(free.size):
        a, b = csr.indptr[node], csr.indptr[node + 1]
        assert csr.indices[a:b].tolist() == cols[node]
        assert csr.data[a:b].tolist() == costs[node]
    # Every edge is there both ways with one cost (the metric is symmetric).
    assert abs(csr - csr.T).max() == 0.0


@pytest.mark.parametrize("connectivity", [8, 16])
def test_offset_costs_are_the_tables_own_values_and_none_when_an_offset_varies(connectivity):
    rng = np.random.default_rng(connectivity)
    free = rng.random((11, 14)) < 0.7
    plain = build_grid_graph(free, 0.05, connectivity)
    nb, cost = plain.edge_table
    N = plain.num_nodes
    costs = plain.offset_costs
    assert costs is not None
    for k in range(len(plain.offsets)):
        edges = nb[:N, k] < N
        assert edges.any()
        assert (cost[:N, k][edges] == costs[k]).all()  # (bit for bit, not only close)
    weighted = build_grid_graph(free, 0.05, connectivity, zeta=rng.uniform(0.5, 2.0, free.shape))
    assert weighted.offset_costs is None


@pytest.mark.parametrize("connectivity", [8, 16])
@pytest.mark.parametrize("resolution", [0.05, 0.1, 0.07, 0.0196078431372549, 1.0])
def test_the_uniform_costs_of_local_searches_are_the_whole_graphs_bit_for_bit(connectivity,
                                                                             resolution):
    # (the hypot of the offset times the resolution is not the hypot of the displacement on
    # diagonals at 0.05 or 0.1 m: a robot's local search and a whole search then tie apart)
    free = np.ones((6, 7), dtype=bool)
    graph = build_grid_graph(free, resolution, connectivity)
    assert graph.uniform_costs is not None and graph.offset_costs is not None
    assert graph.uniform_costs.tolist() == graph.offset_costs.tolist()
