"""Planar poses between frames, and the newest transform tree a robot has heard (``/tf``).

A pose ``(x, y, yaw)`` of frame B in frame A is the transform A <- B. :func:`compose` chains
them (A <- B, B <- C gives A <- C), :func:`invert` turns A <- B into B <- A. :class:`FrameTree`
keeps, for each child frame, its parent and the newest transform parent <- child (REP 105: each
frame has one parent), and :meth:`FrameTree.lookup` walks from a frame up to an ancestor -
``map <- base_link`` through ``odom`` (and any frames between, such as ``base_footprint``) -
the way a real robot's AMCL or slam_toolbox gives its pose. Only the planar part of a transform
is kept (z, roll and pitch are dropped).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Pose = tuple[float, float, float]


def compose(a_b: Pose, b_c: Pose) -> Pose:
    """A <- C from A <- B and B <- C."""
    x, y, t = a_b
    c, s = math.cos(t), math.sin(t)
    return (x + c * b_c[0] - s * b_c[1], y + s * b_c[0] + c * b_c[1],
            math.atan2(math.sin(t + b_c[2]), math.cos(t + b_c[2])))


def invert(a_b: Pose) -> Pose:
    """B <- A from A <- B."""
    x, y, t = a_b
    c, s = math.cos(t), math.sin(t)
    return (-c * x - s * y, s * x - c * y, math.atan2(math.sin(-t), math.cos(-t)))


@dataclass
class Link:
    parent: str
    pose: Pose  # parent <- child
    stamp: float  # [s]; static transforms: -inf


class FrameTree:
    """See module docstring. Frame names are compared without a leading '/'."""

    MAX_DEPTH = 32  # a longer chain is a loop in someone's tree

    def __init__(self) -> None:
        self.links: dict[str, Link] = {}

    @staticmethod
    def _name(frame: str) -> str:
        return frame.lstrip("/")

    def set(self, parent: str, child: str, pose: Pose, stamp: float) -> None:
        """parent <- child at ``stamp``; an older transform than the one kept is ignored."""
        child, parent = self._name(child), self._name(parent)
        if not child or not parent or child == parent:
            raise ValueError(f"a transform needs two different frames (got {parent!r} <- "
                             f"{child!r})")
        if not all(math.isfinite(v) for v in pose):
            raise ValueError(f"transform {parent} <- {child} is not finite: {pose}")
        old = self.links.get(child)
        if old is None or old.parent != parent or stamp >= old.stamp:
            x, y, yaw = (float(v) for v in pose)
            self.links[child] = Link(parent, (x, y, yaw), stamp)

    def lookup(self, target: str, source: str) -> tuple[Pose, float] | None:
        """``target <- source`` and the oldest stamp on the way (None if ``target`` is not an
        ancestor of ``source`` in what was heard)."""
        target, frame = self._name(target), self._name(source)
        pose: Pose = (0.0, 0.0, 0.0)
        stamp = math.inf
        for _ in range(self.MAX_DEPTH):
            if frame == target:
                return pose, stamp
            link = self.links.get(frame)
            if link is None:
                return None
            pose = compose(link.pose, pose)
            stamp = min(stamp, link.stamp if math.isfinite(link.stamp) else math.inf)
            frame = link.parent
        return None
