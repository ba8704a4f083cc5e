"""The stack's own messages (interfaces/coverage_msgs): built, and with the type hashes that
nodes built from this version announce - a change to a message changes its hash, and nodes of
the old and the new version no longer talk (update the hash here on purpose, never by accident);
tf2_msgs, built here too, with the upstream hash."""

from __future__ import annotations

import pytest
from rosutil import RosClient, domain_id

HASHES = {
    "LockstepTick": "RIHS01_3a871c373118d9a3de4ead182bba819f89a98eb90ac04bfda313b4a455e0ad43",
    "LockstepReport": "RIHS01_791805ffc8c00e0966431cc90025254e4128d16fd06fd1c56c5592f02bf0b1f7",
    "RobotState": "RIHS01_663224977c0aba1a1e9ed7b106f648aa6953ab6b8ab6a73f1bb007eeef9f8a97",
    "WorldStatus": "RIHS01_6616ba3753495967fd1c316f91c59d25b3c351eb915d074d3a08c020d20e938b",
}


def test_the_messages_have_their_type_hashes():
    import coverage_msgs.msg as msgs

    client = RosClient(domain_id(8), "hash_check")
    try:
        for name, want in HASHES.items():
            client.node.create_publisher(getattr(msgs, name), f"/hash_{name}", 10)
            info = client.node.get_publishers_info_by_topic(f"/hash_{name}")
            assert info[0].topic_type == f"coverage_msgs/msg/{name}"
            assert str(info[0].topic_type_hash) == want, name
    finally:
        client.close()


def test_the_modes_of_a_coverage_state_are_the_strategies_modes():
    """RobotState's MODE_* constants are the strategies' modes, in their order."""
    from coverage_msgs.msg import RobotState

    from coverage_ros.core.strategies.base import MODES

    for i, mode in enumerate(MODES):
        assert getattr(RobotState, f"MODE_{mode.upper()}") == i
    assert RobotState.MODE_NONE > len(MODES) and RobotState.MODE_OTHER > len(MODES)
    with pytest.raises(AttributeError):
        RobotState.MODE_NO_SUCH_MODE  # noqa: B018


#: tf2_msgs/msg/TFMessage as every Jazzy install reports it (ros2 topic info -v).
UPSTREAM_HASH = "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"


def test_tf2_msgs_is_built_with_the_upstream_type_hash():
    from tf2_msgs.msg import TFMessage

    client = RosClient(domain_id(9), "hash_check")
    try:
        client.node.create_publisher(TFMessage, "/tf", 10)
        info = client.node.get_publishers_info_by_topic("/tf")
        assert [str(i.topic_type_hash) for i in info] == [UPSTREAM_HASH]
        assert info[0].topic_type == "tf2_msgs/msg/TFMessage"
    finally:
        client.close()
