"""RViz markers: the live marker node of a team (one outline per robot, stable ids, deleted when
a robot leaves)."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest
from conftest import NO_ESCAPE, entry_point
from rosutil import NodeProcess, RosClient, domain_id, spin_until_exit

from coverage_ros.nodes import conversions as conv


@pytest.mark.slow
@pytest.mark.lockstep
def test_a_team_shows_in_rviz_markers_and_a_robot_that_leaves_is_cleared(tmp_path):
    from visualization_msgs.msg import Marker, MarkerArray

    domain = domain_id(4)
    out = tmp_path / "team"
    client = RosClient(domain, "marker_watch")
    arrays = client.subscribe("/coverage/markers", MarkerArray)
    # Lock-step at most twice real time: a silent robot's markers go after 3 s of wall time.
    proc = subprocess.Popen(
        [entry_point("coverage-team"), "--quiet", "--world", "empty",
         "--robots", "3", "--duration", "30", "--seed", "1", "--kill", "2@12", "--lockstep",
         "--rtf", "2", *NO_ESCAPE,
         "--out", str(out), "--domain-id", str(domain)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        err = spin_until_exit(client, proc, 240)
    finally:
        client.close()
    assert proc.returncode == 0, err[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["metrics"]["H"] < summary["metrics"]["H_start"]
    assert len(arrays) >= 10
    outlines: dict[int, int] = {}
    added_last = -1  # the last array that added a marker of robot 2
    for k, arr in enumerate(arrays):
        keys = [(m.ns, m.id) for m in arr.markers]
        assert len(keys) == len(set(keys)) <= 3 * len(conv.MARKER_KINDS)  # replaced, not added
        assert {m.ns for m in arr.markers} <= set(conv.MARKER_KINDS)
        for m in arr.markers:
            assert m.id in (0, 1, 2) and m.header.frame_id == "map"
            if m.ns == "cell" and m.action == Marker.ADD:
                assert m.type == Marker.LINE_LIST and len(m.points) >= 8
                outlines[m.id] = outlines.get(m.id, 0) + 1
            if m.id == 2 and m.action == Marker.ADD:
                added_last = k
    assert all(outlines.get(i, 0) >= 3 for i in (0, 1, 2)), outlines
    # No robot's markers go while the team runs: a team held at a tick is still waited for.
    for rid in (0, 1, 2):
        last_add = max(k for k, arr in enumerate(arrays) for m in arr.markers
                       if (m.id, m.action) == (rid, Marker.ADD))
        assert not [k for k, arr in enumerate(arrays[:last_add]) for m in arr.markers
                    if (m.ns, m.id, m.action) == ("generator", rid, Marker.DELETE)], rid
    # Robot 2's markers go for good once it is killed.
    deletions = [(k, m.header.stamp) for k, arr in enumerate(arrays) for m in arr.markers
                 if k > added_last and (m.ns, m.id, m.action) == ("cell", 2, Marker.DELETE)]
    markers_log = (out / "logs" / "markers.log").read_text()[-3000:]
    assert deletions, f"robot 2's markers were never deleted for good; markers.log:\n" \
        f"{markers_log}\nlauncher:\n{err[-2000:]}"
    killed_at = summary["robots"][2]["lost_at"]  # [s] sim time
    # (stamped by the marker node's own clock: it may trail the world's by the /clock messages
    # it has not read yet, up to a second of sim time on a loaded machine at --rtf 2)
    assert conv.from_time_msg(deletions[0][1]) >= killed_at - 2.0, (deletions[0], killed_at)
    modes = {m.text for arr in arrays for m in arr.markers if m.ns == "mode"}
    assert any(t.startswith("robot_0: ") and t != "robot_0: " for t in modes), modes


def test_a_silent_robot_is_taken_off_in_wall_time_while_the_simulation_clock_stands_still():
    """A paused simulation (/clock standing still at 5 s) still gets marker arrays, and a robot
    whose state stops is deleted after ``stale_after`` seconds of wall time."""
    from coverage_msgs.msg import RobotState
    from rosgraph_msgs.msg import Clock
    from visualization_msgs.msg import Marker, MarkerArray

    from coverage_ros.nodes.qos import TEAM_QOS

    domain = domain_id(13)
    client = RosClient(domain, "marker_watch")
    arrays = client.subscribe("/coverage/markers", MarkerArray)
    clock = client.publisher("/clock", Clock)
    state = client.publisher("/robot_1/coverage_state", RobotState, TEAM_QOS)
    cmd = [sys.executable, "-m", "coverage_ros.nodes.marker_node", "--ros-args",
           "-p", "use_sim_time:=true", "-p", "stale_after:=2.0"]
    stamp = conv.to_time_msg(5.0)

    def shown(action: int) -> bool:
        return any((m.ns, m.id, m.action) == ("generator", 1, action)
                   for arr in arrays for m in arr.markers)

    try:
        with NodeProcess(cmd, domain) as node:
            clock.publish(Clock(clock=stamp))
            last = time.monotonic()

            def speak() -> bool:
                nonlocal last
                assert node.alive(), node.output()
                if time.monotonic() - last >= 0.2:
                    last = time.monotonic()  # (before sending: the node hears it later)
                    state.publish(conv.coverage_state_msg(stamp, {"x": 1.0, "y": 2.0},
                                                          robot_id=1))
                return shown(Marker.ADD)

            client.spin_until(speak, 60.0, "robot 1's generator marker")
            assert not shown(Marker.DELETE)
            client.spin_until(lambda: shown(Marker.DELETE), 20.0,
                              f"robot 1's markers deleted; marker_node:\n{node.output()}")
            # (the node heard the last state after it was sent: silent at least this long)
            assert time.monotonic() - last > 2.0
            assert "robot 1 silent or gone" in node.output()
    finally:
        client.close()


def test_a_robot_a_lockstep_world_waits_for_keeps_its_markers_while_the_team_is_held():
    """A lock-step team held at one tick (the world re-publishes it, robot 1 among its members)
    publishes no states: robot 1 keeps its markers past ``stale_after``; once the world's ticks
    no longer list it (dropped), they are deleted."""
    from coverage_msgs.msg import LockstepTick, RobotState
    from rosgraph_msgs.msg import Clock
    from visualization_msgs.msg import Marker, MarkerArray

    from coverage_ros.nodes.qos import TEAM_QOS, TICK_QOS

    domain = domain_id(16)
    client = RosClient(domain, "marker_watch")
    arrays = client.subscribe("/coverage/markers", MarkerArray)
    clock = client.publisher("/clock", Clock)
    ticks = client.publisher("/world/tick", LockstepTick, TICK_QOS)
    state = client.publisher("/robot_1/coverage_state", RobotState, TEAM_QOS)
    cmd = [sys.executable, "-m", "coverage_ros.nodes.marker_node", "--ros-args",
           "-p", "use_sim_time:=true", "-p", "stale_after:=1.0"]
    stamp = conv.to_time_msg(5.0)
    members = [1]
    sent = {"state": -1.0, "tick": -1.0}

    def deleted() -> bool:
        return any((m.ns, m.id, m.action) == ("generator", 1, Marker.DELETE)
                   for arr in arrays for m in arr.markers)

    def every(kind: str, period: float) -> bool:
        if time.monotonic() - sent[kind] < period:
            return False
        sent[kind] = time.monotonic()
        return True

    def tick() -> None:
        if every("tick", 0.5):  # (as the world re-sends a tick it waits on)
            ticks.publish(LockstepTick(tick=50, stamp=stamp, previous=stamp, period=0.1,
                                       robots=members))

    try:
        with NodeProcess(cmd, domain) as node:
            clock.publish(Clock(clock=stamp))

            def speak() -> bool:
                assert node.alive(), node.output()
                tick()
                if every("state", 0.2):
                    state.publish(conv.coverage_state_msg(stamp, {"x": 1.0, "y": 2.0},
                                                          robot_id=1))
                return any((m.ns, m.id, m.action) == ("generator", 1, Marker.ADD)
                           for arr in arrays for m in arr.markers)

            client.spin_until(speak, 60.0, "robot 1's generator marker")
            held = time.monotonic()

            def held_four_times_stale_after() -> bool:  # (ticks only, no state)
                tick()
                return time.monotonic() - held > 4.0

            client.spin_until(held_four_times_stale_after, 10.0, "a held tick")
            assert not deleted(), node.output()
            latest = arrays[-1].markers  # (still drawn, not only left undeleted)
            assert ("generator", 1, Marker.ADD) in {(m.ns, m.id, m.action) for m in latest}
            members.clear()  # the world dropped robot 1

            def dropped_and_deleted() -> bool:
                tick()
                return deleted()

            client.spin_until(dropped_and_deleted, 20.0,
                              f"robot 1's markers deleted; marker_node:\n{node.output()}")
            assert "robot 1 silent or gone" in node.output()
    finally:
        client.close()
