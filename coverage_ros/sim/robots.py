"""One simulated differential-drive robot: a pymunk disc driven like a unicycle.

Drive model (top-down pattern of pymunk's ``examples/tank.py``): a kinematic *control body*
carries the wanted velocity; a ``PivotJoint`` with ``max_bias = 0`` pulls the robot's linear
velocity towards it and a ``GearJoint`` its angular velocity, each with a bounded force that acts
like tyre friction. Contacts are hard constraints, so walls and other robots win over the drive:
a robot pushing a wall stays at the wall.

Each physics step the command ``(v, w)`` is clamped to ``|v| <= v_max``, ``|w| <= w_max``, then
the applied velocities move towards it by at most ``a_max * dt`` and ``alpha_max * dt``. The
linear velocity is set along the heading at the middle of the step that applies it, which makes
the discrete motion follow the unicycle model's arcs to second order, one physics step late.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymunk

from coverage_ros.core.world import RobotSpec
from coverage_ros.core.world.robot import TB3_RADIUS

ROBOT_MASS = 1.0  # [kg] TurtleBot3 Burger (about 1 kg); scaled with footprint area for others
DRIVE_ACCEL = 50.0  # [m/s^2] drive force limit / mass: 20x a_max, so commands are tracked exactly
DRIVE_ANGULAR_ACCEL = 200.0  # [rad/s^2] drive torque limit / moment, likewise
ROBOT_FRICTION = 0.3  # [-] Coulomb friction against walls and robots (plastic on paint)


def _step_towards(current: float, target: float, max_delta: float) -> float:
    return current + min(max(target - current, -max_delta), max_delta)


@dataclass
class OdomState:
    """Odometry of one robot in its odom frame (fixed at the spawn pose)."""

    x: float = 0.0  # [m]
    y: float = 0.0  # [m]
    yaw: float = 0.0  # [rad]
    var_xy: float = 0.0  # [m^2] accumulated position variance (noise model)
    var_yaw: float = 0.0  # [rad^2] accumulated heading variance


class Robot:
    """A robot's bodies, shapes, command state and counters (owned by the simulator's world)."""

    def __init__(self, robot_id: int, spec: RobotSpec, pose: tuple[float, float, float],
                 group: int, collision_type: int, spawn_time: float) -> None:
        self.id = robot_id
        self.spec = spec
        mass = ROBOT_MASS * (spec.radius / TB3_RADIUS) ** 2
        moment = pymunk.moment_for_circle(mass, 0.0, spec.radius)
        self.body = pymunk.Body(mass, moment)
        self.body.position = (pose[0], pose[1])
        self.body.angle = pose[2]
        self.shape = pymunk.Circle(self.body, spec.radius)
        self.shape.friction = ROBOT_FRICTION
        self.shape.elasticity = 0.0
        self.shape.collision_type = collision_type
        self.shape.filter = pymunk.ShapeFilter(group=group)
        self.control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.control.position = self.body.position
        pivot = pymunk.PivotJoint(self.control, self.body, (0, 0), (0, 0))
        pivot.max_bias = 0.0  # correct velocity only, never position
        pivot.max_force = mass * DRIVE_ACCEL
        gear = pymunk.GearJoint(self.control, self.body, 0.0, 1.0)
        gear.max_bias = 0.0
        gear.max_force = moment * DRIVE_ANGULAR_ACCEL
        self.joints = (pivot, gear)
        self.group = group
        # Command state.
        self.cmd_v = 0.0  # [m/s] last accepted command, clamped
        self.cmd_w = 0.0  # [rad/s]
        self.last_cmd_time = -math.inf  # [s] sim time of the last command
        self.v = 0.0  # [m/s] applied (rate-limited) velocity
        self.w = 0.0  # [rad/s]
        # Bookkeeping.
        self.spawn_pose = (float(pose[0]), float(pose[1]), float(pose[2]))
        self.spawn_time = spawn_time
        self.prev_pose = self.spawn_pose
        self.path_length = 0.0  # [m] distance travelled by the true pose
        self.robot_collisions = 0  # contact begins with other robots
        self.wall_collisions = 0  # contact begins with static geometry
        self.min_separation = math.inf  # [m] closest centre distance to another robot so far
        self.odom = OdomState()
        self.next_scan_time = math.inf  # [s] sim time of the next lidar scan
        self.scans = 0

    @property
    def collisions(self) -> int:
        return self.robot_collisions + self.wall_collisions

    @property
    def pymunk_objects(self) -> tuple:
        return (self.body, self.shape, self.control, *self.joints)

    # ------------------------------------------------------------------ state
    def pose(self) -> tuple[float, float, float]:
        """True ``(x, y, yaw)`` in the map frame ([m], [m], [rad], yaw wrapped to [-pi, pi))."""
        p = self.body.position
        yaw = (self.body.angle + math.pi) % (2.0 * math.pi) - math.pi
        return float(p.x), float(p.y), yaw

    def body_twist(self) -> tuple[float, float, float]:
        """True velocity in the robot frame: ``(vx forward, vy left, w)`` [m/s, m/s, rad/s]."""
        v = self.body.velocity
        c, s = math.cos(self.body.angle), math.sin(self.body.angle)
        return c * v.x + s * v.y, -s * v.x + c * v.y, float(self.body.angular_velocity)

    # ------------------------------------------------------------------ control
    def set_command(self, v: float, w: float, now: float) -> None:
        """Accept a command ``(v, w)`` [m/s, rad/s] at sim time ``now`` (clamped to limits).
        Raises ValueError for non-finite values."""
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ValueError(f"command must be finite (got v={v!r}, w={w!r})")
        self.cmd_v = min(max(float(v), -self.spec.v_max), self.spec.v_max)
        self.cmd_w = min(max(float(w), -self.spec.w_max), self.spec.w_max)
        self.last_cmd_time = now

    def apply_drive(self, now: float, dt: float, cmd_timeout: float) -> None:
        """Set the control body's velocity for the next step of ``dt`` [s]."""
        if now - self.last_cmd_time > cmd_timeout:
            self.cmd_v = self.cmd_w = 0.0
        self.v = _step_towards(self.v, self.cmd_v, self.spec.a_max * dt)
        self.w = _step_towards(self.w, self.cmd_w, self.spec.alpha_max * dt)
        # pymunk integrates positions with the velocities solved in the *previous* step, so a
        # command acts one step later (20 ms at 50 Hz, like a real drive's latency). Point the
        # velocity along the heading at the middle of the step that will use it.
        heading = self.body.angle + (self.body.angular_velocity + 0.5 * self.w) * dt
        self.control.velocity = (self.v * math.cos(heading), self.v * math.sin(heading))
        self.control.angular_velocity = self.w

    def after_step(self, rng: np.random.Generator | None, trans_noise: float,
                   rot_noise: float) -> None:
        """Update path length and odometry from the motion of the last step.

        Odometry integrates the true motion increment in the robot frame; with noise, each
        increment gets Gaussian errors of std ``trans_noise * sqrt(|ds|)`` (along and across)
        and ``rot_noise * sqrt(|dyaw|)``, a random walk whose variance grows linearly with the
        distance driven and the angle turned (none while standing still).
        """
        x0, y0, a0 = self.prev_pose
        p = self.body.position
        x1, y1, a1 = float(p.x), float(p.y), float(self.body.angle)
        self.prev_pose = (x1, y1, a1)
        dx, dy, da = x1 - x0, y1 - y0, a1 - a0
        ds = math.hypot(dx, dy)
        self.path_length += ds
        if ds == 0.0 and da == 0.0:
            return
        c, s = math.cos(a0), math.sin(a0)
        fx, fy = c * dx + s * dy, -s * dx + c * dy  # increment in the previous robot frame
        odom = self.odom
        if rng is not None and (trans_noise > 0 or rot_noise > 0):
            sd_t = trans_noise * math.sqrt(ds)
            sd_r = rot_noise * math.sqrt(abs(da))
            n = rng.normal(0.0, 1.0, size=3)
            fx += sd_t * n[0]
            fy += sd_t * n[1]
            da += sd_r * n[2]
            odom.var_xy += sd_t * sd_t
            odom.var_yaw += sd_r * sd_r
        c, s = math.cos(odom.yaw), math.sin(odom.yaw)
        odom.x += c * fx - s * fy
        odom.y += s * fx + c * fy
        odom.yaw = (odom.yaw + da + math.pi) % (2.0 * math.pi) - math.pi
