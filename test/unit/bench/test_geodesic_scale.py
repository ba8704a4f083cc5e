"""scripts/bench_core's geodesic sweep summary: per kind of scenario, how many meet the target."""

from __future__ import annotations

from coverage_ros.bench.geodesic_scale import by_kind


def test_kinds_keep_their_order_and_count_the_scenarios_within_the_target():
    rows = [{"kind": "gaussians", "geodesic_ms": 6.0}, {"kind": "obstacles", "geodesic_ms": 30.0},
            {"kind": "gaussians", "geodesic_ms": 10.0}, {"kind": "uniform", "geodesic_ms": 5.0},
            {"kind": "gaussians", "geodesic_ms": 12.5}, {"kind": "obstacles", "geodesic_ms": 9.0}]
    kinds = by_kind(rows, 10.0)
    assert list(kinds) == ["gaussians", "obstacles", "uniform"]
    assert kinds["gaussians"] == {"scenarios": 3, "median_ms": 10.0, "worst_ms": 12.5, "met": 2}
    assert kinds["obstacles"] == {"scenarios": 2, "median_ms": 19.5, "worst_ms": 30.0, "met": 1}
    assert kinds["uniform"]["met"] == 1 == kinds["uniform"]["scenarios"]
