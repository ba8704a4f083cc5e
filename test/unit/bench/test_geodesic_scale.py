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


def test_the_dijkstra_calls_of_a_team_step_are_timed_and_the_step_is_unchanged():
    import numpy as np
    from scipy.sparse.csgraph import dijkstra

    from coverage_ros.bench.geodesic_scale import _dijkstra_timed
    from coverage_ros.core.geodesic import visible_first
    from coverage_ros.core.geodesic.world_domain import world_domain
    from coverage_ros.core.offline.lloyd_team import GeodesicTeam
    from coverage_ros.core.world import load_world
    from coverage_ros.core.world.placement import team_starts
    from coverage_ros.worlds import resolve_world_path

    world = load_world(resolve_world_path("office"))
    specs = [world.robot_spec(i) for i in range(8)]
    starts = team_starts(world, specs, None, 0)[:, :2]
    plain = GeodesicTeam(world_domain(world, specs[0].radius)).step(starts)
    with _dijkstra_timed() as spent:
        timed = GeodesicTeam(world_domain(world, specs[0].radius)).step(starts)
    assert spent and all(t > 0 for t in spent)  # (rooms hidden from the cluster: searched)
    assert visible_first.dijkstra is dijkstra  # (put back)
    np.testing.assert_array_equal(timed.goals, plain.goals)
    np.testing.assert_array_equal(timed.masses, plain.masses)
