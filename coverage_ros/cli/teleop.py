"""coverage-teleop: drive one robot of a running team from the terminal.

    coverage-teleop --robot 0 [--domain-id N]

Arrow keys (or w/a/s/d) change the speed and turn rate in steps, space stops, ``m`` hands the
robot to its strategy and back, ``q`` (or Ctrl-C) stops and quits. The command is sent on
``/robot_<id>/teleop/cmd_vel`` (``geometry_msgs/Twist``, what ``teleop_twist_keyboard``
publishes) ten times a second: the robot stops by itself if the terminal goes quiet. On start
the robot is switched to manual (``set_manual``) if it was not, and switched back at the end;
its speed limits are read from its ``coverage_state`` and shown. The robot's safety filter
still has the last word: it will not drive the robot into a wall or another robot.

For machines without the ROS CLI; with it, ``ros2 run teleop_twist_keyboard
teleop_twist_keyboard --ros-args -r cmd_vel:=/robot_0/teleop/cmd_vel`` does the same.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import select
import signal
import sys
import time
from dataclasses import dataclass

from coverage_ros.cli.interrupts import Interrupts
from coverage_ros.core.world.robot import TB3_V_MAX, TB3_W_MAX

PUBLISH_PERIOD = 0.1  # [s] the command is repeated this often (robot_node's timeout: 0.5 s)
STEPS = 5  # key presses from standstill to the speed limit

#: Escape sequences of the arrow keys, and the letter keys that do the same.
KEYS = {"\x1b[A": "faster", "w": "faster", "\x1b[B": "slower", "s": "slower",
        "\x1b[D": "left", "a": "left", "\x1b[C": "right", "d": "right",
        " ": "stop", "x": "stop", "m": "mode", "q": "quit", "\x03": "quit"}


@dataclass
class TeleopCommand:
    """The (v, w) a person has set with the keys, within the robot's limits."""

    v_max: float = TB3_V_MAX
    w_max: float = TB3_W_MAX
    v: float = 0.0
    w: float = 0.0

    def press(self, action: str) -> None:
        dv, dw = self.v_max / STEPS, self.w_max / STEPS
        if action == "faster":
            self.v += dv
        elif action == "slower":
            self.v -= dv
        elif action == "left":
            self.w += dw
        elif action == "right":
            self.w -= dw
        elif action == "stop":
            self.v = self.w = 0.0
        self.clip()

    def clip(self) -> None:
        self.v = round(min(max(self.v, -self.v_max), self.v_max), 6)
        self.w = round(min(max(self.w, -self.w_max), self.w_max), 6)


def split_keys(data: str) -> list[str]:
    """The key presses in ``data`` (arrow keys' escape sequences kept whole; unknown bytes
    dropped)."""
    out, i = [], 0
    while i < len(data):
        if data.startswith("\x1b[", i) and i + 2 < len(data):
            out.append(data[i:i + 3])
            i += 3
        else:
            out.append(data[i])
            i += 1
    return [k for k in out if k in KEYS]


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="coverage-teleop", description=__doc__.split("\n")[0])
    ap.add_argument("--robot", type=int, required=True, help="id of the robot to drive")
    ap.add_argument("--prefix", default="robot_", help="namespace prefix of the team's robots")
    ap.add_argument("--domain-id", type=int, help="ROS_DOMAIN_ID of the team (coverage-team "
                    "prints it at start)")
    ap.add_argument("--v-max", type=float, default=TB3_V_MAX,
                    help="[m/s] speed limit until the robot's own is heard")
    ap.add_argument("--w-max", type=float, default=TB3_W_MAX, help="[rad/s] turn rate limit")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.robot < 0:
        print(f"coverage-teleop: error: --robot must be >= 0, got {args.robot}", file=sys.stderr)
        return 2
    if not (args.v_max > 0 and args.w_max > 0):
        print("coverage-teleop: error: --v-max and --w-max must be > 0", file=sys.stderr)
        return 2
    if args.domain_id is not None:
        os.environ["ROS_DOMAIN_ID"] = str(args.domain_id)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return Teleop(args).run()


class Teleop:
    def __init__(self, args: argparse.Namespace) -> None:
        import rclpy
        from coverage_msgs.msg import RobotState
        from geometry_msgs.msg import Twist
        from rclpy.node import Node
        from std_srvs.srv import SetBool

        from coverage_ros.nodes.shm_ports import warn_removed_ports

        self.rclpy, self.Twist, self.SetBool = rclpy, Twist, SetBool
        # Not rclpy's signal handlers: they shut ROS down at once, and the robot, never told,
        # stayed manual. Ctrl-C, SIGTERM and a closed terminal end the loop instead (below).
        warn_removed_ports("coverage-teleop")
        rclpy.init(signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        ns = f"/{args.prefix}{args.robot}"
        self.ns = ns
        self.node = Node("coverage_teleop")
        self.pub = self.node.create_publisher(Twist, f"{ns}/teleop/cmd_vel", 10)
        self.manual_client = self.node.create_client(SetBool, f"{ns}/set_manual")
        self.node.create_subscription(RobotState, f"{ns}/coverage_state", self._on_state, 10)
        self.cmd = TeleopCommand(args.v_max, args.w_max)
        self.robot_manual: bool | None = None  # as the robot last reported
        self.took_over = False
        self.note = "waiting for the robot"

    def _on_state(self, msg) -> None:
        if math.isfinite(msg.v_max) and msg.v_max > 0:
            self.cmd.v_max = float(msg.v_max)
            self.cmd.clip()
        if msg.mode != msg.MODE_NONE:  # (before the first update it says nothing of it)
            self.robot_manual = bool(msg.manual)

    def _set_manual(self, manual: bool, wait: float = 2.0) -> bool:
        if not self.manual_client.wait_for_service(timeout_sec=wait):
            self.note = f"no service {self.ns}/set_manual"
            return False
        future = self.manual_client.call_async(self.SetBool.Request(data=manual))
        self.rclpy.spin_until_future_complete(self.node, future, timeout_sec=wait)
        ok = future.done() and future.result() is not None and future.result().success
        self.note = (future.result().message if ok else "set_manual failed")
        if ok:
            self.robot_manual = manual
        return ok

    def _send(self, v: float, w: float) -> None:
        msg = self.Twist()
        msg.linear.x, msg.angular.z = float(v), float(w)
        self.pub.publish(msg)

    def _show(self) -> None:
        mode = {None: "?", True: "manual", False: "autonomous"}[self.robot_manual]
        c = self.cmd
        line = (f"{self.ns}: {mode} | v {c.v:+.2f} / {c.v_max:.2f} m/s | w {c.w:+.2f} / "
                f"{c.w_max:.2f} rad/s | arrows: speed/turn, space: stop, m: manual/auto, "
                f"q: quit | {self.note}")
        sys.stderr.write("\r\x1b[K" + line[:200])
        sys.stderr.flush()

    def run(self) -> int:
        raw = _RawTerminal()
        # All three raise KeyboardInterrupt - SIGINT too: a process started in the background
        # of a script inherits SIGINT ignored, and Python then leaves it so.
        stop = Interrupts((signal.SIGINT, signal.SIGTERM, signal.SIGHUP))
        try:
            with raw:
                deadline = time.monotonic() + 5.0
                while self.robot_manual is None and time.monotonic() < deadline:
                    self.rclpy.spin_once(self.node, timeout_sec=0.1)
                if self.robot_manual is not True and self._set_manual(True):
                    self.took_over = True
                last = 0.0
                while True:
                    ready, _, _ = select.select([sys.stdin], [], [], 0.02)
                    if ready:
                        data = os.read(sys.stdin.fileno(), 64).decode(errors="ignore")
                        if not data:  # stdin closed
                            break
                        actions = [KEYS[k] for k in split_keys(data)]
                        if "quit" in actions:
                            break
                        for a in actions:
                            if a == "mode":
                                self._set_manual(not self.robot_manual)
                            else:
                                self.cmd.press(a)
                    self.rclpy.spin_once(self.node, timeout_sec=0.0)
                    now = time.monotonic()
                    if now - last >= PUBLISH_PERIOD:
                        last = now
                        self._send(self.cmd.v, self.cmd.w)
                        self._show()
        except (KeyboardInterrupt, RuntimeError) as exc:
            if not stop.caused(exc):
                raise
        finally:
            stop.ignore()  # (the robot is handed back whatever comes next)
            with contextlib.suppress(Exception):
                self._send(0.0, 0.0)
                if self.took_over:
                    self._set_manual(False)
                sys.stderr.write(f"\ncoverage-teleop: stopped; {self.note}\n")
                self.node.destroy_node()
                self.rclpy.try_shutdown()
        return 0


class _RawTerminal:
    """Key presses without Enter while inside (a no-op when stdin is not a terminal)."""

    def __enter__(self):
        self.saved = None
        if sys.stdin.isatty():
            import termios
            import tty

            self.saved = termios.tcgetattr(sys.stdin.fileno())
            tty.setcbreak(sys.stdin.fileno())
        return self

    def __exit__(self, *exc) -> None:
        if self.saved is not None:
            import termios

            termios.tcsetattr(sys.stdin.fileno(), termios.TCSADRAIN, self.saved)


if __name__ == "__main__":
    sys.exit(main())
