"""A region of interest on the live team: the team re-spreads into a polygon published on
/coverage/region mid-run (the region's checks: unit/core/world/test_region.py)."""

from __future__ import annotations

import json
import os
import signal
import subprocess

import numpy as np
import pytest
from conftest import REPO, entry_point
from rosutil import RosClient, domain_id, spin_until_exit

from coverage_ros.core.geodesic.tessellation import Generator, tessellate
from coverage_ros.core.geodesic.world_domain import world_domain
from coverage_ros.core.world import load_world
from coverage_ros.core.world.region import Region, parse_region_text


def team_cmd(*args: str) -> list[str]:
    """coverage-team with ``args``."""
    return [entry_point("coverage-team"), "--quiet", *args]


SQUARE = "5,5;7.5,5;7.5,7.5;5,7.5"


def region_cost(world, square, positions) -> float:
    domain = world_domain(world, 0.105)
    region = Region().with_polygon(square)
    d = domain.with_density(region.restrict(domain.density, world.grid, domain.free))
    return float(tessellate(d, [Generator(p) for p in positions]).cost)


@pytest.mark.slow
@pytest.mark.lockstep
def test_a_polygon_published_mid_run_draws_the_team_into_it(tmp_path):
    """Three robots spread over the empty 8 m x 8 m world; a polygon (and a malformed one) is
    published on /coverage/region after 10 s: all robots end inside the polygon, and the
    coverage cost over it falls by more than 40 % from where they were when it came."""
    from coverage_msgs.msg import RobotState
    from geometry_msgs.msg import PolygonStamped

    from coverage_ros.nodes import conversions as conv
    from coverage_ros.nodes.region_input import REGION_QOS, REGION_TOPIC

    domain = domain_id(5)
    out = tmp_path / "team"
    client = RosClient(domain, "region_user")
    states = {i: client.subscribe(f"/robot_{i}/coverage_state", RobotState) for i in range(3)}
    pub = client.node.create_publisher(PolygonStamped, REGION_TOPIC, REGION_QOS)
    square = parse_region_text(SQUARE)
    # In lock-step at most four times real time: the polygon goes out once this process has
    # read a state of 12 s of sim time from every robot - later by four times its lag on a
    # loaded machine - and the robots have until 60 s to reach it.
    proc = subprocess.Popen(team_cmd("--world", "empty", "--robots", "3", "--duration", "60",
                                     "--seed", "1", "--lockstep", "--rtf", "4", "--out", str(out),
                                     "--domain-id", str(domain)),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        def clock():
            xs = [states[i][-1] for i in range(3) if states[i]]
            return min(conv.from_time_msg(m.header.stamp) for m in xs) if len(xs) == 3 else 0
        client.spin_until(lambda: clock() > 12.0, 120, "the team running for 12 s")
        at_publish = [conv.coverage_state_values(states[i][-1]) for i in range(3)]
        pub.publish(conv.polygon_msg(conv.to_time_msg(0.0), np.array([[0, 0], [1, 1.0]])))
        pub.publish(conv.polygon_msg(conv.to_time_msg(0.0), square))
        err = spin_until_exit(client, proc, 200)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        client.close()
    assert proc.returncode == 0, err[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    world = load_world(REPO / "config" / "worlds" / "empty.yaml")
    before = np.array([[v["x"], v["y"]] for v in at_publish])
    final = np.array([r["final"][:2] for r in summary["robots"]])
    lo, hi = square.min(axis=0) - 0.05, square.max(axis=0) + 0.05
    assert ((final >= lo) & (final <= hi)).all(), final
    H0, H1 = region_cost(world, square, before), region_cost(world, square, final)
    print(f"H over the region: {H0:.2f} when published -> {H1:.2f} at the end")
    assert H1 <= 0.6 * H0, (H0, H1)
    assert np.allclose(summary["region"]["polygons"], [square.tolist()])
    assert summary["metrics"]["H"] == pytest.approx(H1, rel=0.05)  # scored over the region
    for i in range(3):
        log = (out / "logs" / f"robot_{i}.log").read_text()
        assert "region of interest now: 1 polygon" in log
        assert "dropped a polygon on /coverage/region: region: needs at least 3 points" in log
