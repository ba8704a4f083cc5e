"""The test suite's DDS domain ids: one per test offset and slot, none shared between the slots
of a run, none the launcher may draw for a team started without ``--domain-id``."""

from __future__ import annotations

import pytest
from rosutil import TEST_DOMAINS, domain_id

from coverage_ros.cli.team.domains import FRESH_RANGE, MAX_DOMAIN_ID


@pytest.mark.parametrize("base", [100, 137, 199])
def test_a_runs_ids_are_distinct_usable_and_outside_the_launchers_fresh_range(base, monkeypatch):
    monkeypatch.setenv("COVERAGE_ROS_TEST_DOMAIN_BASE", str(base))
    ids = []
    for slot in range(4):
        monkeypatch.setenv("COVERAGE_ROS_TEST_DOMAIN_SLOT", str(slot))
        ids += [domain_id(offset) for offset in range(30)]
    assert len(set(ids)) == 120
    assert all(1 <= d <= MAX_DOMAIN_ID and not FRESH_RANGE[0] <= d <= FRESH_RANGE[1]
               for d in ids)


def test_the_test_ids_are_every_usable_id_but_the_default_and_the_fresh_range():
    assert len(TEST_DOMAINS) == MAX_DOMAIN_ID - (FRESH_RANGE[1] - FRESH_RANGE[0] + 1)
    assert 0 not in TEST_DOMAINS and {99, 200, MAX_DOMAIN_ID} <= set(TEST_DOMAINS)
