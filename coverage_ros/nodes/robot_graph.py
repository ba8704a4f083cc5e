"""Finding a team's robots in the ROS graph: every ``/<prefix><id>/<name>`` topic of a type
(:func:`robot_topics`), and how often a robot looks (:class:`GraphLooks`)."""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator

#: Once a robot hears its whole team, it looks at the ROS graph for new neighbours only every
#: this many discovery periods: a look at the graph of 32 robot processes costs ~9 ms, and one
#: a second in each was a sixth of a robot process's CPU (its restarts keep their topic names:
#: the subscription stays, no look needed).
SLOW_LOOKS = 10


def robot_topics(names_and_types: Iterable[tuple[str, list[str]]], prefix: str, name: str,
                 msg_type: str | None = None) -> Iterator[tuple[int, str]]:
    """``(robot id, topic)`` of every ``/<prefix><id>/<name>`` (of ``msg_type``, e.g.
    ``coverage_msgs/msg/RobotState``, when given) in ``get_topic_names_and_types()``."""
    for rid, kind, topic, types in robot_topic_kinds(names_and_types, prefix):
        if kind == name and (msg_type is None or msg_type in types):
            yield rid, topic


def robot_topic_kinds(names_and_types: Iterable[tuple[str, list[str]]], prefix: str
                      ) -> Iterator[tuple[int, str, str, list[str]]]:
    """``(robot id, name, topic, types)`` of every ``/<prefix><id>/<name>`` topic (one level:
    ``/robot_3/teleop/cmd_vel`` is not one)."""
    pattern = re.compile(rf"/{re.escape(prefix)}(\d+)/(\w+)")
    for topic, types in names_and_types:
        m = pattern.fullmatch(topic)
        if m:
            yield int(m.group(1)), m.group(2), topic, list(types)


STATE_TYPE = "coverage_msgs/msg/RobotState"


def state_topics(names_and_types: Iterable[tuple[str, list[str]]],
                 prefix: str) -> Iterator[tuple[int, str]]:
    """``(robot id, topic)`` of every ``/<prefix><id>/coverage_state`` of the right type."""
    return robot_topics(names_and_types, prefix, "coverage_state", STATE_TYPE)


class GraphLooks:
    """Whether a robot looks at the ROS graph this discovery period: every period while it
    knows fewer than ``team_size - 1`` neighbours (or ``team_size`` is 0: unknown), else every
    :data:`SLOW_LOOKS`-th."""

    def __init__(self, team_size: int) -> None:
        self.team_size = team_size
        self.periods = 0

    def due(self, known: int) -> bool:
        """``known``: neighbours found so far (< 0: always look)."""
        self.periods += 1
        whole = 0 < self.team_size - 1 <= known
        return not whole or self.periods % SLOW_LOOKS == 0
