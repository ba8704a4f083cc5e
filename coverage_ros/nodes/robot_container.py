"""robot_container: several robots of a coverage team in one process.

The ROS 2 composition idiom for ``robot_node``: every robot is still its own node
(``/<prefix><id>/coverage_robot``) with exactly robot_node's topics, services and parameters,
but the robots share the process - its interpreter and libraries, the world file, the map and
its graph - and one subscription per neighbour's ``coverage_state``
(:mod:`~coverage_ros.nodes.robot_shared`). All nodes run on one single-threaded executor; each
robot keeps its own coverage update thread. See README "Several robots per process".

    ros2 run coverage_ros robot_container 0 1 2 3 --ros-args --params-file robots.yaml

Parameters come as for any composed node: a parameters file whose sections name each node
(``/robot_3/coverage_robot: {ros__parameters: {...}}``, ``/**`` for all of them) or ``-p``
for all. Each robot's ``robot_id`` is set from its id. A start-up error of any robot ends the
process (exit code 2, one line naming it), as it would end a robot_node.
"""

from __future__ import annotations

import argparse
import sys

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.utilities import remove_ros_args

from coverage_ros.errors import ConfigError
from coverage_ros.nodes.lockstep_member import LockstepDriver, LockstepRobot
from coverage_ros.nodes.robot_node import DISCOVERY_PERIOD, RobotNode
from coverage_ros.nodes.robot_shared import SharedInputs, StateHub
from coverage_ros.nodes.runner import STARTUP_ERRORS, run_nodes
from coverage_ros.nodes.throttle import WarnThrottle


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="robot_container", description=__doc__.split("\n")[0])
    ap.add_argument("ids", type=int, nargs="+", metavar="ID", help="the robots' ids")
    ap.add_argument("--prefix", default="robot_",
                    help="namespace of robot ID: /<prefix><ID> (robot_node's robot_prefix)")
    args = ap.parse_args(remove_ros_args(argv)[1:])
    if len(set(args.ids)) != len(args.ids) or min(args.ids) < 0:
        ap.error(f"ids must be distinct and >= 0, got {args.ids}")
    return args


#: Coverage updates of the process's robots that run at once (see robot_shared).
UPDATE_SLOTS = 1


class ContainerNode(Node):
    """The process's own node: finds the neighbours and runs the :class:`StateHub`; with sim
    time, it also carries the one ``/clock`` subscription of the process."""

    def __init__(self, robots: list[RobotNode], prefix: str) -> None:
        sim = [r for r in robots if r.get_parameter("use_sim_time").value]
        super().__init__(f"robot_container_{min(r.robot_id for r in robots)}",
                         parameter_overrides=[Parameter("use_sim_time", value=bool(sim))])
        throttle = WarnThrottle(self.get_logger().warning)
        self.hub = StateHub(self, robots, prefix, throttle.warn)
        self.driver: LockstepDriver | None = None
        lockstep = [r.lockstep for r in robots if r.lockstep is not None]
        if lockstep:  # one driver answers the ticks for them all; neighbours from the ticks
            self.driver = LockstepDriver(self, list[LockstepRobot](lockstep), throttle.warn,
                                         self.hub.roster)
            for member in lockstep:
                member.driver = self.driver
        if len(lockstep) < len(robots):
            self.create_timer(DISCOVERY_PERIOD, self.hub.discover,
                              clock=Clock(clock_type=ClockType.STEADY_TIME))
        shared = sum(self._share_clock(r) for r in sim)
        self.get_logger().info(f"{len(robots)} robots in one process: "
                               f"{', '.join(r.get_namespace() for r in robots)}"
                               + (f"; one /clock subscription for {shared}" if shared else ""))

    def _share_clock(self, robot: RobotNode) -> bool:
        """Drive ``robot``'s clock from this node's /clock subscription instead of its own:
        every /clock message would otherwise wake each robot of the process (10 Hz each).
        rclpy keeps a node's time source private; without it the robot keeps its own."""
        source = getattr(robot, "_time_source", None)
        if source is None or not hasattr(source, "detach_node"):
            return False
        source.detach_node()  # drops the robot's /clock subscription
        self._time_source.attach_clock(robot.get_clock())  # type: ignore[arg-type]  # a ROSClock
        return True


def _make_nodes(args: argparse.Namespace) -> list[Node]:
    shared = SharedInputs(update_slots=UPDATE_SLOTS)
    robots = []
    for rid in args.ids:
        try:
            robots.append(RobotNode(["--ros-args", "-r", f"__ns:=/{args.prefix}{rid}",
                                     "-p", f"robot_id:={rid}",
                                     "-p", f"robot_prefix:={args.prefix}"],
                                    shared=shared, hub=True))
        except STARTUP_ERRORS as exc:  # say which robot's parameters are wrong
            raise ConfigError(f"robot {rid}: {exc}") from None
    # The container first: its clean-up stops the lock-step driver before the robots stop.
    return [ContainerNode(robots, args.prefix), *robots]


def _stop(node: Node) -> None:
    if isinstance(node, RobotNode):
        node.stop()
    elif isinstance(node, ContainerNode):
        if node.driver is not None:
            node.driver.close()
            node.get_logger().info(node.driver.summary())
        node.get_logger().info(f"{node.hub.received} states received, "
                               f"{node.hub.delivered} delivered to local robots")


def main(args: list[str] | None = None) -> int:
    argv = list(sys.argv if args is None else args)
    parsed = parse_arguments(argv)
    return run_nodes("robot_container", lambda: _make_nodes(parsed), argv, cleanup=_stop)


if __name__ == "__main__":
    sys.exit(main())
