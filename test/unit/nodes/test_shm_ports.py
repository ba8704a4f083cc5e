"""Removal of the Fast DDS shared-memory ports a killed process left half made
(nodes/shm_ports.py)."""

from __future__ import annotations

import os

from coverage_ros.nodes.shm_ports import STALE_AGE, broken_ports, remove_broken_ports


def _port(folder, name: str, header: bytes | None, age: float, now: float):
    path = folder / name
    path.write_bytes(b"" if header is None else header + bytes(60))
    os.utime(path, (now - age, now - age))
    return path


def test_only_old_unsized_or_unmarked_ports_are_broken(tmp_path):
    now = 1_000_000.0
    old = STALE_AGE + 1.0
    unsized = _port(tmp_path, "fastrtps_port7007", None, old, now)
    initialising = _port(tmp_path, "fastrtps_port7411", (1).to_bytes(4, "little"), old, now)
    healthy = _port(tmp_path, "fastrtps_port7413", (2).to_bytes(4, "little"), old, now)
    being_made = _port(tmp_path, "fastrtps_port7415", None, 0.5, now)  # (its creator is at it)
    lock = _port(tmp_path, "fastrtps_port7417_el", None, old, now)
    segment = _port(tmp_path, "fastrtps_0123456789abcdef", None, old, now)
    assert sorted(broken_ports(tmp_path, now)) == sorted([unsized, initialising])
    assert sorted(remove_broken_ports(tmp_path, now)) == ["fastrtps_port7007",
                                                           "fastrtps_port7411"]
    assert not unsized.exists() and not initialising.exists()
    assert all(p.exists() for p in (healthy, being_made, lock, segment))
    assert remove_broken_ports(tmp_path, now) == []


def test_a_missing_folder_has_no_broken_ports(tmp_path):
    assert broken_ports(tmp_path / "none") == []


def test_a_start_up_timeout_names_the_broken_ports_it_removed(tmp_path, monkeypatch):
    from coverage_ros.nodes import shm_ports

    monkeypatch.setattr(shm_ports, "SHM_DIR", tmp_path)
    assert shm_ports.startup_hint() == ""
    now = os.path.getmtime(tmp_path)
    _port(tmp_path, "fastrtps_port7007", None, STALE_AGE + 60.0, now)
    hint = shm_ports.startup_hint()
    assert "1 broken Fast DDS shared-memory file(s)" in hint and "fastrtps_port7007" in hint
    assert "run again" in hint and not (tmp_path / "fastrtps_port7007").exists()


def test_a_process_started_again_keeps_to_udp_unless_its_transports_are_chosen():
    from coverage_ros.nodes.shm_ports import restarted_env

    assert restarted_env({"ROS_DOMAIN_ID": "3"}) == {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
    assert restarted_env({"FASTDDS_BUILTIN_TRANSPORTS": "LARGE_DATA"}) == {}
