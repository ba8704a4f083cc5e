"""The team launcher's monitor: a small rclpy node that follows a running team and scores it.

It listens to ``/clock``, ``/world/robots`` (poses, collisions, path lengths, separations:
a few messages a second for the whole team, so that the monitor takes little of the CPU the
robots need) and every robot's ``coverage_state``; shows progress; kills and restarts robots
on schedule; and at the end computes the summary metrics (definitions in README "Team launcher"):

* ``H`` / ``H_start``: geodesic coverage cost (density-weighted, as ``coverage-plan``) of the
  final / start positions of the robots still running;
* ``mass_deviation_I``: Lee & Lee's I of the final geodesic cell masses;
* ``coverage_ratio``: free area within its sensing radius and line of sight of some robot;
* ``min_separation``: smallest distance between two robot centres during the run (the
  simulator checks every physics step);
* ``converged_at``: first sim time from which H stayed within 2 % of its final value;
* ``H_series``: ``[[t, H], ...]``, H every METRICS_PERIOD of wall time, or up to
  METRICS_LONGEST times less often where one tessellation takes longer than METRICS_SHARE of
  that (t: sim time since the team was ready).
"""

from __future__ import annotations

import contextlib
import math
import signal
import subprocess
import sys
import time

import numpy as np
import rclpy
from coverage_msgs.msg import RobotState, WorldStatus
from geometry_msgs.msg import PolygonStamped
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Int32
from std_srvs.srv import SetBool

from coverage_ros.cli.team.exploration import TeamExploration
from coverage_ros.cli.team.lockstep import LockstepObserver, run_lockstep
from coverage_ros.cli.team.processes import ProcessStats
from coverage_ros.cli.team.summary import converged_at
from coverage_ros.core.geodesic.tessellation import Generator, fast_tessellate
from coverage_ros.core.metrics import coverage_ratio, mass_deviation
from coverage_ros.core.world.region import Region
from coverage_ros.core.world.robot import NUMBER_FIELDS
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.clock_guard import ClockGuard
from coverage_ros.nodes.qos import quiet_subscription
from coverage_ros.nodes.region_input import REGION_QOS, REGION_TOPIC, RegionInput

EXPLORE_PERIOD = 1.0  # [s] wall time between scores of an exploring team's merged belief
#: Share of one core the launcher spends on H samples at most, up to METRICS_LONGEST periods
#: between samples: a tessellation of 64 robots on depot takes 0.4-2 s on two busy cores, CPU
#: the robots need.
METRICS_SHARE = 0.1
METRICS_LONGEST = 3.0
TRACK_STEP = 0.05  # [m] a robot's path in summary.png gets a point every this far
#: [s] wall time without /clock advancing after which the run is given up (the world node is
#: stuck: a CI run's world blocked for good in a DDS publish of /clock after a robot restart).
CLOCK_STALL = 60.0


class TeamTracker:
    def __init__(self, domain, world, team, args, faults, procs, say,
                 region: Region | None = None, relaunch=None,
                 process_of: dict[int, str] | None = None) -> None:
        """``faults``: sorted ``(sim time after ready, robot id, "kill" | "restart")``;
        ``relaunch(robot_id)`` starts a robot's process again (restarts); ``process_of``:
        the launcher's name of each robot's process (default ``robot_<id>``)."""
        self.domain, self.world, self.args = domain, world, args
        self.base_domain = domain  # the world's density; a region of interest restricts it
        self.region_set_at: float | None = None
        self.team = {m.id: m for m in team}
        self.starts = np.array([m.start for m in team], dtype=np.float64)
        self.faults, self.relaunch, self.restarted = list(faults), relaunch, {}
        self.procs, self.say = procs, say
        self.process_of = process_of or {m.id: f"robot_{m.id}" for m in team}
        n = args.robots
        # The launcher handles SIGINT itself (children stopped, a summary written): rclpy's
        # handler would shut the context down under the tracker's spin instead.
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        self.node = Node("coverage_team")
        self.sim_time = 0.0
        self.clock_guard, self.clock_error, self._clock_checked = ClockGuard(), "", 0.0
        self.ready_at: float | None = None
        self.poses: dict[int, np.ndarray] = {}
        self.tracks: dict[int, list[tuple[float, float]]] = {}  # driven paths, for the picture
        self.status: dict[int, dict[str, float]] = {}  # SimulatedRobot's fields by robot
        self.states_seen: set[int] = set()
        self.lost: dict[int, float] = {}
        self.H_samples: list[tuple[float, float]] = []
        self.proc_stats: ProcessStats | None = None  # made in run(), once the children exist
        self.node.create_subscription(Clock, "/clock", self._on_clock, 10)
        self.node.create_subscription(WorldStatus, "/world/robots", self._on_status, 10)
        self.remove_pub = self.node.create_publisher(Int32, "/world/remove", 10)
        # Only to see every robot come up (dropped once the team is ready).
        self.state_subs = [self.node.create_subscription(
            RobotState, f"/robot_{i}/coverage_state", lambda m, i=i: self.states_seen.add(i),
            10, event_callbacks=quiet_subscription()) for i in range(n)]
        # Pause and resume the whole team: forwarded to every robot's own service.
        self.pause_clients = {i: self.node.create_client(SetBool, f"/robot_{i}/pause")
                              for i in range(n)}
        self.node.create_service(SetBool, "/team/pause", self._on_pause)
        # The region of interest: scored as the robots take it (--region is published here).
        self.regions = RegionInput(self.node, self._set_region,
                                   lambda _, text: self.say(f"\n  {text}"))
        self.region_pub = self.node.create_publisher(PolygonStamped, REGION_TOPIC, REGION_QOS)
        for poly in (region or Region()).polygons:
            self.region_pub.publish(conv.polygon_msg(conv.to_time_msg(0.0), poly))
        self.observer = None
        if args.lockstep:
            self.observer = LockstepObserver(self.node, list(range(n)), evidence=args.explore)
        self.exploration = None
        if getattr(args, "explore", False):
            self.exploration = TeamExploration(
                self.node, world, self.starts, list(range(n)), max(m.spec.radius for m in team),
                lockstep=None if self.observer is None else self.observer.inbox.put_evidence)

    # ------------------------------------------------------------------ inputs
    def _set_region(self, region: Region) -> None:
        base = self.base_domain
        self.domain = base if region.everywhere else base.with_density(
            region.restrict(base.density, base.geometry, base.free))
        self.region_set_at = self.sim_time

    def _on_clock(self, msg: Clock) -> None:
        t = conv.from_time_msg(msg.clock)
        self.clock_error = self.clock_error or self.clock_guard.check_time(t)
        self.sim_time = max(self.sim_time, t)

    def _on_status(self, msg: WorldStatus) -> None:
        if self.observer is not None:
            self.observer.status_stamp = max(self.observer.status_stamp,
                                             conv.stamp_ns(msg.header.stamp))
        for i, values in conv.world_status_robots(msg).items():
            self.status[i] = values
            if i not in self.lost:
                self.poses[i] = np.array([values[k] for k in ("x", "y", "yaw")])
                track = self.tracks.setdefault(i, [])
                if not track or np.hypot(*(self.poses[i][:2] - track[-1])) > TRACK_STEP:
                    track.append(tuple(self.poses[i][:2]))

    def _on_pause(self, request, response):
        asked = []
        for i in self.alive():
            client = self.pause_clients[i]
            if client.service_is_ready():
                client.call_async(SetBool.Request(data=request.data))
                asked.append(i)
        missing = sorted(set(self.alive()) - set(asked))
        verb = "pausing" if request.data else "resuming"
        response.success = not missing
        response.message = f"{verb} robots {asked}" + (
            f"; robots {missing} have no pause service yet" if missing else "")
        self.say(f"\n  {response.message}")
        return response

    @property
    def min_sep(self) -> float:
        return min((st.get("min_separation", math.inf) for st in self.status.values()),
                   default=math.inf)

    # ------------------------------------------------------------------ main loop
    def alive(self) -> list[int]:
        return [i for i in range(self.args.robots) if i not in self.lost]

    def run(self, startup_timeout: float, progress_period: float, metrics_period: float) -> None:
        n = self.args.robots
        t0 = time.monotonic()
        if getattr(self.args, "stats", False):
            self.proc_stats = ProcessStats(self.procs)
        if self.observer is not None:
            try:
                run_lockstep(self, self.observer, startup_timeout, progress_period)
            finally:
                self.run_span = (self.sim_time - getattr(self, "sim_start", self.sim_time),
                                 time.monotonic() - getattr(self, "wall_start", time.monotonic()))
            if not self.H_samples or self.H_samples[-1][0] != self.sim_time:
                self.H_samples.append((self.sim_time, self.cost()))
            self.progress(self.ready_at + self.args.duration, final=True)
            return
        self.say("  waiting for the world and the robots ...")
        while self.ready_at is None:
            rclpy.spin_once(self.node, timeout_sec=0.1)
            self.check_children(starting=True)
            if len(self.states_seen) == n and len(self.poses) == n:
                self.ready_at = self.sim_time
            elif time.monotonic() - t0 > startup_timeout:
                missing = sorted(set(range(n)) - self.states_seen)
                raise RuntimeError(f"robots {missing} did not start within "
                                   f"{startup_timeout:g} s (see their logs)")
        self.team_ready(t0)
        end = self.ready_at + self.args.duration
        last_progress = last_metrics = last_explored = 0.0
        metrics_wait = metrics_period
        until = getattr(self.args, "until_explored", None)
        advanced = (self.sim_time, time.monotonic())  # the clock's last step: (sim, wall)
        try:
            while self.sim_time < end:
                rclpy.spin_once(self.node, timeout_sec=0.05)
                self.check_children()
                if self.sim_time > advanced[0]:
                    advanced = (self.sim_time, time.monotonic())
                elif time.monotonic() - advanced[1] > CLOCK_STALL:
                    raise RuntimeError(
                        f"the simulation clock stood at {self.sim_time:.1f} s for "
                        f"{CLOCK_STALL:g} s of wall time: the world node is stuck (see "
                        "logs/world.log)")
                while self.faults and self.sim_time - self.ready_at >= self.faults[0][0]:
                    _, rid, action = self.faults.pop(0)
                    self.kill(rid) if action == "kill" else self.restart(rid)
                now = time.monotonic()
                if self.proc_stats is not None:
                    self.proc_stats.sample(now)
                if now - last_metrics >= metrics_wait:
                    last_metrics = now
                    self.H_samples.append((self.sim_time, self.cost()))
                    took = time.monotonic() - now
                    metrics_wait = min(METRICS_LONGEST * metrics_period,
                                       max(metrics_period, took / METRICS_SHARE))
                if self.exploration is not None and now - last_explored >= EXPLORE_PERIOD:
                    last_explored = now
                    fraction = self.exploration.sample(self.sim_time - self.ready_at)
                    if until is not None and fraction >= until:
                        self.say(f"\n  explored {100 * fraction:.1f} % at sim time "
                                 f"{self.sim_time - self.ready_at:.1f} s: stopping")
                        break
                if now - last_progress >= progress_period:
                    last_progress = now
                    self.progress(end)
        finally:
            # The run's real-time factor is measured over the run only: not start-up, and not
            # the shutdown of the processes that follows.
            self.run_span = (self.sim_time - self.sim_start, time.monotonic() - self.wall_start)
        self.H_samples.append((self.sim_time, self.cost()))
        self.progress(end, final=True)

    def team_ready(self, t0: float) -> None:
        """Every robot is up (``t0``: wall time the launcher began waiting)."""
        self.ready_at = self.sim_time
        # Both anchors of the run's real-time factor are taken now, before the first cost
        # evaluation (which takes a while on big maps and would leave sim_start stale).
        self.wall_start = time.monotonic()
        self.sim_start = self.sim_time
        for sub in self.state_subs:
            self.node.destroy_subscription(sub)
        self.say(f"  team ready at sim time {self.ready_at:.1f} s after "
                 f"{self.wall_start - t0:.1f} s wall")
        self.H_samples.append((self.ready_at, self.cost()))

    def check_children(self, starting: bool = False) -> None:
        now = time.monotonic()
        if now - self._clock_checked >= 1.0:  # a graph query: once a second is enough
            self._clock_checked = now
            self.clock_error = self.clock_error or self.clock_guard.check_publishers(
                self.node.count_publishers("/clock"))
        if self.clock_error:
            raise RuntimeError(f"{self.clock_error}; stopping the team")
        world = self.procs.children.get("world")
        if world is not None and not world.alive:
            raise RuntimeError(f"world_node exited ({world.popen.returncode}):\n"
                               f"{self.procs.tail(world)}")
        for i in self.alive():
            child = self.procs.children.get(self.process_of.get(i, ""))
            if child is not None and not child.alive and starting:
                raise RuntimeError(f"robot {i} exited during start-up "
                                   f"({child.popen.returncode}):\n{self.procs.tail(child)}")
            if child is not None and not child.alive and i not in self.lost:
                self.say(f"\n  robot {i} exited ({child.popen.returncode}):\n"
                         f"{self.procs.tail(child)}")
                self.lost[i] = self.sim_time

    def restart(self, rid: int) -> None:
        """The robot's process dies (SIGKILL) and starts again at once with the same id and
        parameters; its body stays where it is, as a robot whose software crashed would."""
        t = self.sim_time - self.ready_at
        self.say(f"\n  restarting robot {rid} at sim time {t:.1f} s")
        self.procs.signal(f"robot_{rid}", signal.SIGKILL)
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.procs.children[f"robot_{rid}"].popen.wait(timeout=3.0)
        self.relaunch(rid)
        self.restarted.setdefault(rid, []).append(round(t, 2))

    def kill(self, rid: int) -> None:
        self.say(f"\n  killing robot {rid} at sim time {self.sim_time:.1f} s")
        self.procs.signal(f"robot_{rid}", signal.SIGKILL)
        self.remove_pub.publish(Int32(data=rid))
        self.lost[rid] = self.sim_time
        self.poses.pop(rid, None)

    def _present(self) -> list[int]:
        return [i for i in self.alive() if i in self.poses]

    def _generators(self, ids: list[int], positions: np.ndarray) -> list[Generator]:
        """Each robot as the tessellation sees it: its position and its own power weight."""
        return [Generator(p, self.team[i].spec.power_weight)
                for i, p in zip(ids, positions, strict=True)]

    def cost(self) -> float:
        ids = self._present()
        if not ids:
            return math.nan
        P = np.array([self.poses[i][:2] for i in ids])
        return float(fast_tessellate(self.domain, self._generators(ids, P)).cost)

    def progress(self, end: float, final: bool = False) -> None:
        if self.args.quiet:
            return
        span = end - self.ready_at
        frac = min(1.0, max(0.0, (self.sim_time - self.ready_at) / span))
        wall = time.monotonic() - self.wall_start
        rtf = (self.sim_time - self.sim_start) / wall if wall > 0 else 0.0
        H = self.H_samples[-1][1] if self.H_samples else math.nan
        bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
        collisions = sum(int(s.get("collisions", 0)) for s in self.status.values())
        explored = "" if self.exploration is None else \
            f"  explored {100 * self.exploration.explored:5.1f} %"
        line = (f"  [{bar}] sim {self.sim_time - self.ready_at:6.1f}/{span:g} s  rtf {rtf:4.2f}"
                f"  H {H:9.4g}  collisions {collisions}{explored}")
        if sys.stderr.isatty():
            print("\r" + line, end="\n" if final else "", file=sys.stderr, flush=True)
        elif final or int(frac * 10) != getattr(self, "_decile", -1):
            self._decile = int(frac * 10)
            print(line, file=sys.stderr, flush=True)

    # ------------------------------------------------------------------ results
    def summary(self, wall_time: float, interrupted: bool) -> dict:
        alive = self._present()
        P = np.array([self.poses[i][:2] for i in alive]).reshape(-1, 2)
        tess = fast_tessellate(self.domain, self._generators(alive, P)) if len(P) else None
        H_start = float(fast_tessellate(self.domain, self._generators(
            list(range(self.args.robots)), self.starts[:, :2])).cost)
        sensing = np.array([self.team[i].spec.sensor_radius for i in alive])
        robots = []
        for i in range(self.args.robots):
            st = self.status.get(i, {})
            final = self.poses.get(i)
            robots.append({
                "id": i, "start": self.starts[i].round(4).tolist(),
                "final": None if final is None else np.round(final, 4).tolist(),
                "path_length": round(st.get("path_length", 0.0), 4),
                "collisions": int(st.get("collisions", 0)),
                "robot_collisions": int(st.get("robot_collisions", 0)),
                "wall_collisions": int(st.get("wall_collisions", 0)),
                "spec": self.team[i].spec.numbers(), "role": self.team[i].role,
                "body": self._body(st),
                **({"lost_at": round(self.lost[i], 2)} if i in self.lost else {}),
                **({"restarted_at": self.restarted[i]} if i in self.restarted else {})})
        H = float(tess.cost) if tess is not None else math.nan
        return {
            "world": str(self.world.source), "strategy": self.args.strategy,
            "seed": self.args.seed, "sim_time": round(self.sim_time, 3),
            "wall_time": round(wall_time, 3),
            "rtf": round(self.run_span[0] / max(self.run_span[1], 1e-9), 3)
            if hasattr(self, "run_span") else 0.0,
            "ready_at": None if self.ready_at is None else round(self.ready_at, 3),
            "interrupted": interrupted, "robots": robots,
            "metrics": {
                "H": H if math.isfinite(H) else None, "H_start": H_start,
                "mass_deviation_I": mass_deviation(tess.masses) if tess is not None else None,
                "coverage_ratio": coverage_ratio(self.world.grid, P, sensing),
                "min_separation": self.min_sep if math.isfinite(self.min_sep) else None,
                "converged_at": converged_at(self.H_samples, H, self.ready_at),
                "H_series": [[round(t - (self.ready_at or 0.0), 2), round(h, 6)]
                             for t, h in self.H_samples if math.isfinite(h)],
            },
            "region": {"polygons": [p.round(4).tolist() for p in self.regions.region.polygons],
                       "set_at": None if self.region_set_at is None or self.ready_at is None
                       else round(max(self.region_set_at - self.ready_at, 0.0), 3)},
            **({"processes": self.proc_stats.report(len(self.team))}
               if self.proc_stats is not None else {}),
            **({"exploration": self.exploration.summary()}
               if self.exploration is not None else {}),
        }

    def picture(self, path) -> None:
        """``summary.png`` (:func:`coverage_ros.viz.png.render_team`)."""
        from coverage_ros.viz.png import render_team

        alive = self._present()
        P = np.array([self.poses[i][:2] for i in alive]).reshape(-1, 2)
        own = fast_tessellate(self.domain, self._generators(alive, P)).labels if len(P) else None
        n = self.args.robots
        render_team(path, self.world.grid, own, alive, self.starts,
                    [self.tracks.get(i, []) for i in range(n)], self.domain.density,
                    f"{self.args.strategy}: {n} robots, {self.sim_time:.0f} s")

    @staticmethod
    def _body(status: dict[str, float]) -> dict[str, float]:
        """The simulated body's spec as the world node reports it (empty if it never did)."""
        return {k: float(status[k]) for k in NUMBER_FIELDS if k in status}

    def close(self) -> None:
        self.node.destroy_node()
        rclpy.try_shutdown()
