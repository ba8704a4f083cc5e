"""The live team's layers without ROS (coverage_ros/viz/live_team.py): markers, trajectories,
scans, cells in the robots' colours and metrics, read back from the .rrd file."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rrdutil import cell_rgba, read_rrd, rerun_verify

from coverage_ros.core.world.grid import GridMap
from coverage_ros.viz.colors import robot_color


def test_live_team_layers_without_ros(tmp_path):
    """LiveTeam -> .rrd: markers, trajectory, cells in the robots' colours, metrics."""
    from coverage_ros.viz.live_metrics import LiveMetrics
    from coverage_ros.viz.live_team import LiveRates, LiveTeam
    from coverage_ros.viz.recording import CoverageRecorder

    occ = np.zeros((40, 60), dtype=np.int8)
    occ[:, 30] = 100  # a wall with a door
    occ[18:22, 30] = 0
    grid = GridMap(occ, 0.1)
    warnings = []
    rec = CoverageRecorder("unit-test")
    rec.set_outputs(tmp_path / "team.rrd")
    metrics = LiveMetrics(rec, 0.1, None, lambda key, text: warnings.append(text))
    team = LiveTeam(rec, LiveRates(metrics_period=0.5, cells_period=0.0), metrics)
    team.set_map(grid)
    team.add_robot(3)
    team.add_robot(7)
    for k in range(21):
        t = 0.1 * k
        team.pose(3, t, (1.0 + 0.1 * k, 2.0, 0.0))
        team.pose(7, t, (4.5, 2.0, math.pi))
        team.advance(t)
        while metrics.busy:
            metrics._job.result()
    # A scan that overtakes the pose of its own stamp waits for it.
    assert team.scan(3, 2.05, lambda pose: np.array([[pose[0] + 1.0, pose[1]]]))
    team.pose(3, 2.05, (3.05, 2.0, 0.0))
    cell3 = GridMap(np.full((40, 30), 100), 0.1)  # the left half
    team.cell(3, 2.0, cell3)
    team.cell(7, 2.0, GridMap(np.full((40, 29), 100), 0.1, (3.1, 0.0, 0.0)))
    with pytest.raises(ValueError, match="not finite"):
        team.pose(3, 2.1, (math.nan, 0.0, 0.0))
    team.remove_robot(7)
    metrics.close()
    rec.close()
    assert not warnings
    rows = read_rrd(tmp_path / "team.rrd")
    last_robots = rows["/world/robots"][-1][1]
    assert last_robots["Points3D:labels"] == ["robot_3"]  # 7 left
    first_two = [r for _, r in rows["/world/robots"] if len(r["Points3D:labels"]) == 2]
    assert first_two, "both robots were shown together"
    scans = rows["/world/scans/robot_3"]
    assert len(scans) == 1 and scans[0][0] == pytest.approx(2.05)
    assert scans[0][1]["Points3D:positions"][0][:2] == pytest.approx([4.05, 2.0])
    tail = rows["/world/trajectories/robot_3"][-1][1]["LineStrips3D:strips"][0]
    assert tail[0][:2] == pytest.approx([1.0, 2.0]) and tail[-1][:2] == pytest.approx([3.0, 2.0])
    # Computed cells first (the wall splits them at the door), then the published ones.
    cells = [(t, cell_rgba(r)) for t, r in rows["/world/cells"]]
    assert any(t < 2.0 for t, _ in cells)  # computed ones before the first published cell
    published = cells[-1][1]  # logged at the latest sim time, 2.05 s
    assert tuple(published[5, 5, :3]) == tuple(robot_color(3))
    assert tuple(published[5, 40, :3]) == tuple(robot_color(7))
    assert published[5, 30, 3] == 0  # the wall column is in nobody's published cell
    H = [r["Scalars:scalars"][0] for t, r in rows["/metrics/H"] if t is not None]
    assert len(H) >= 3 and all(h > 0 for h in H)
    m3 = {t: r["Scalars:scalars"][0] for t, r in rows["/metrics/mass/robot_3"] if t is not None}
    m7 = {t: r["Scalars:scalars"][0] for t, r in rows["/metrics/mass/robot_7"] if t is not None}
    from coverage_ros.core.geodesic.domain import CoverageDomain

    total = CoverageDomain.from_grid(grid, 0.1).mass_element.sum()
    # The cells of the robots posed at t cover the free space (robot 7 may miss the first
    # request, made when only robot 3's pose had arrived).
    assert len(set(m3) & set(m7)) >= 2
    for t in m3:
        assert m3[t] + m7.get(t, 0.0) == pytest.approx(total)
    assert rerun_verify(tmp_path / "team.rrd").returncode == 0
