"""The team launcher's monitor: an rclpy node that follows a running team and keeps its
:class:`~coverage_ros.cli.team.summary.RunLog`.

It listens to ``/clock``, ``/world/robots`` (poses, collisions, path lengths, separations:
a few messages a second for the whole team, so that the monitor takes little of the CPU the
robots need) and every robot's ``coverage_state`` until the team is up; shows progress; carries
out the robot faults on schedule (:mod:`.faults`); relays ``/team/pause`` to every robot; follows
the region of interest; samples the coverage cost H every METRICS_PERIOD of wall time, or up to
METRICS_LONGEST times less often where one tessellation takes longer than METRICS_SHARE of
that. In lock-step the same is done at exact ticks (:mod:`.lockstep`).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from functools import partial

import numpy as np
from coverage_msgs.msg import RobotState, WorldStatus
from geometry_msgs.msg import PolygonStamped
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Int32
from std_srvs.srv import SetBool

from coverage_ros.cli.team.exploration import TeamExploration
from coverage_ros.cli.team.faults import KILL, Fault, FaultSchedule
from coverage_ros.cli.team.lockstep import LockstepObserver, run_lockstep
from coverage_ros.cli.team.plan import RunPlan
from coverage_ros.cli.team.processes import ProcessSet, ProcessStats
from coverage_ros.cli.team.settling import SETTLED_BAND, SettleWatch
from coverage_ros.cli.team.summary import RunLog, team_cost
from coverage_ros.core.world.region import Region
from coverage_ros.nodes import conversions as conv
from coverage_ros.nodes.clock_guard import ClockGuard
from coverage_ros.nodes.qos import quiet_subscription
from coverage_ros.nodes.region_input import REGION_QOS, REGION_TOPIC, RegionInput
from coverage_ros.nodes.shm_ports import startup_hint

PROGRESS_PERIOD = 0.5  # [s] wall time between progress refreshes
#: [s] wall time between coverage cost evaluations for the progress bar (a tessellation of a
#: large map costs ~0.5 s of CPU that the robots need more).
METRICS_PERIOD = 10.0
EXPLORE_PERIOD = 1.0  # [s] wall time between scores of an exploring team's merged belief
#: Share of one core the launcher spends on H samples at most, up to METRICS_LONGEST periods
#: between samples (a tessellation of 64 robots on depot takes 0.4-2 s on two busy cores).
METRICS_SHARE = 0.1
METRICS_LONGEST = 3.0
TRACK_STEP = 0.05  # [m] a robot's path in summary.png gets a point every this far
#: [s] wall time without /clock advancing after which the run is given up (the world node is
#: stuck).
CLOCK_STALL = 60.0
#: [s] wall time between looks for children stuck on a broken Fast DDS shared-memory port
#: while the team starts (:meth:`ProcessSet.restart_stuck`).
STUCK_CHECK_PERIOD = 10.0


class TeamMonitor(Node):
    """See module docstring. ``relaunch(robot_id)`` starts a robot's process again (restarts);
    ``say`` prints a line for the user (or nothing with ``--quiet``)."""

    def __init__(self, plan: RunPlan, procs: ProcessSet, say: Callable[[str], object],
                 relaunch: Callable[[int], object]) -> None:
        super().__init__("coverage_team")
        self.plan, self.config, self.procs, self.say = plan, plan.config, procs, say
        self.team = plan.team
        self.n = plan.robots
        self.process_of = {rid: p.name for p in plan.processes for rid in p.ids}
        self.base_domain = self.domain = plan.domain  # a region of interest restricts it
        self.log = RunLog()
        self.clock_guard, self.clock_error, self._clock_checked = ClockGuard(), "", 0.0
        self._stuck_checked = time.monotonic()  # [s] last look for children stuck on a broken port
        self.states_seen: set[int] = set()
        self.proc_stats: ProcessStats | None = None  # made in run(), once the children exist
        self._decile = -1
        self.create_subscription(Clock, "/clock", self._on_clock, 10)
        self.create_subscription(WorldStatus, "/world/robots", self._on_status, 10)
        self.remove_pub = self.create_publisher(Int32, "/world/remove", 10)
        self.faults = FaultSchedule(list(plan.faults), procs, relaunch, self._remove, say)
        # To see every robot come up (dropped once the team is ready, unless --until-settled
        # follows whether robots move between cells).
        self.settle = (None if self.config.until_settled is None
                       else SettleWatch(self.config.until_settled))
        self.state_subs = [self.create_subscription(
            RobotState, f"/robot_{i}/coverage_state", partial(self._state_seen, i),
            10, event_callbacks=quiet_subscription()) for i in range(self.n)]
        # Pause and resume the whole team: forwarded to every robot's own service.
        self.pause_clients = {i: self.create_client(SetBool, f"/robot_{i}/pause")
                              for i in range(self.n)}
        self.create_service(SetBool, "/team/pause", self._on_pause)
        # The region of interest: scored as the robots take it (--region is published here).
        self.regions = RegionInput(self, self._set_region, lambda _, text: self.say(f"\n  {text}"))
        self.region_pub = self.create_publisher(PolygonStamped, REGION_TOPIC, REGION_QOS)
        for poly in self.config.region.polygons:
            self.region_pub.publish(conv.polygon_msg(conv.to_time_msg(0.0), poly))
        self.observer = None
        if self.config.lockstep:
            self.observer = LockstepObserver(self, list(range(self.n)),
                                             evidence=self.config.explore)
        self.exploration = None
        if self.config.explore:
            starts = np.array([m.start for m in self.team], dtype=np.float64)
            self.exploration = TeamExploration(
                self, plan.world, starts, list(range(self.n)), plan.radius,
                lockstep=None if self.observer is None else self.observer.put_evidence)

    # ------------------------------------------------------------------ inputs
    def _state_seen(self, rid: int, msg: RobotState) -> None:
        self.states_seen.add(rid)
        if self.settle is not None:
            # (the tick's own conversion: a stamp compares exactly with a lock-step tick's)
            self.settle.note(rid, msg, conv.stamp_ns(msg.header.stamp) * 1e-9)

    def _set_region(self, region: Region) -> None:
        base = self.base_domain
        self.domain = base if region.everywhere else base.with_density(
            region.restrict(base.density, base.geometry, base.free))
        self.log.region_set_at = self.log.sim_time

    def _on_clock(self, msg: Clock) -> None:
        t = conv.from_time_msg(msg.clock)
        self.clock_error = self.clock_error or self.clock_guard.check_time(t)
        self.log.sim_time = max(self.log.sim_time, t)

    def _on_status(self, msg: WorldStatus) -> None:
        if self.observer is not None:
            self.observer.status_stamp = max(self.observer.status_stamp,
                                             conv.stamp_ns(msg.header.stamp))
        log = self.log
        for i, values in conv.world_status_robots(msg).items():
            log.status[i] = values
            if i not in log.lost:
                pose = np.array([values[k] for k in ("x", "y", "yaw")])
                log.poses[i] = pose
                track = log.tracks.setdefault(i, [])
                if not track or np.hypot(*(pose[:2] - track[-1])) > TRACK_STEP:
                    track.append((float(pose[0]), float(pose[1])))

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response
                  ) -> SetBool.Response:
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

    def _remove(self, rid: int) -> None:
        """A killed robot: its body leaves the world, it leaves the scores."""
        self.remove_pub.publish(Int32(data=rid))
        self.log.lost[rid] = self.log.sim_time
        self.log.poses.pop(rid, None)

    # ------------------------------------------------------------------ the run
    def alive(self) -> list[int]:
        return [i for i in range(self.n) if i not in self.log.lost]

    def cost(self) -> float:
        return team_cost(self.domain, self.team, self.log)

    def apply_faults(self, t: float, slack: float = 0.0) -> None:
        """Carry out the faults due at ``t`` [s since the team was ready]."""
        for fault in self.faults.due(t, slack):
            self._apply(fault, t)

    def _apply(self, fault: Fault, t: float) -> None:
        if fault.action == KILL:
            self.faults.kill(fault.robot, self.log.sim_time)
        else:
            self.faults.restart(fault.robot, t)
            self.log.restarted.setdefault(fault.robot, []).append(round(t, 2))

    def run(self) -> None:
        """Follow the team from its start-up to the end of the run (RuntimeError: it failed)."""
        if self.config.stats:
            self.proc_stats = ProcessStats(self.procs)
        try:
            if self.observer is not None:
                run_lockstep(self, self.observer, self.plan.startup_timeout, PROGRESS_PERIOD)
            else:
                self._run_real_time()
        finally:
            # The run's real-time factor is measured over the run only: not start-up, and not
            # the shutdown of the processes that follows.
            if self.log.sim_start is not None and self.log.wall_start is not None:
                self.log.run_span = (self.log.sim_time - self.log.sim_start,
                                     time.monotonic() - self.log.wall_start)
        if not self.log.H_samples or self.log.H_samples[-1][0] != self.log.sim_time:
            self.log.H_samples.append((self.log.sim_time, self.cost()))
        self.progress(final=True)

    def finish(self) -> RunLog:
        """The log, with what is known only at the end."""
        self.log.region = list(self.regions.region.polygons)
        if self.exploration is not None:
            self.log.exploration = self.exploration.summary()
        if self.proc_stats is not None:
            self.log.processes = self.proc_stats.report(self.n)
        return self.log

    def _run_real_time(self) -> None:
        import rclpy

        log = self.log
        t0 = time.monotonic()
        self.say("  waiting for the world and the robots ...")
        while log.ready_at is None:
            rclpy.spin_once(self, timeout_sec=0.1)
            self.check_children(starting=True)
            if len(self.states_seen) == self.n and len(log.poses) == self.n:
                self.team_ready(t0)
            elif time.monotonic() - t0 > self.plan.startup_timeout:
                missing = sorted(set(range(self.n)) - self.states_seen)
                raise RuntimeError(f"robots {missing} did not start within "
                                   f"{self.plan.startup_timeout:g} s (see their logs)"
                                   f"{startup_hint()}")
        end = self.end
        ready = log.sim_start if log.sim_start is not None else log.sim_time  # (= ready_at)
        last_progress = last_metrics = last_explored = 0.0
        metrics_wait = METRICS_PERIOD
        until = self.config.until_explored
        advanced = (log.sim_time, time.monotonic())  # the clock's last step: (sim, wall)
        while log.sim_time < end:
            rclpy.spin_once(self, timeout_sec=0.05)
            self.check_children()
            if log.sim_time > advanced[0]:
                advanced = (log.sim_time, time.monotonic())
            elif time.monotonic() - advanced[1] > CLOCK_STALL:
                raise RuntimeError(
                    f"the simulation clock stood at {log.sim_time:.1f} s for {CLOCK_STALL:g} s "
                    "of wall time: the world node is stuck (see logs/world.log)")
            self.apply_faults(log.sim_time - ready)
            now = time.monotonic()
            if self.proc_stats is not None:
                self.proc_stats.sample(now)
            if now - last_metrics >= metrics_wait and log.H_samples[-1][0] != log.sim_time:
                last_metrics = now  # (one sample per sim time: the ready one comes first)
                log.H_samples.append((log.sim_time, self.cost()))
                took = time.monotonic() - now
                metrics_wait = min(METRICS_LONGEST * METRICS_PERIOD,
                                   max(METRICS_PERIOD, took / METRICS_SHARE))
                if self.settled_enough(log.sim_time):
                    break
            if self.exploration is not None and now - last_explored >= EXPLORE_PERIOD:
                last_explored = now
                if self.explored_enough(self.exploration.sample(log.sim_time - ready),
                                        until):
                    break
            if now - last_progress >= PROGRESS_PERIOD:
                last_progress = now
                self.progress()

    @property
    def end(self) -> float:
        """[s] sim time the run ends at (once the team is ready)."""
        return (self.log.ready_at or 0.0) + self.config.duration

    def explored_enough(self, fraction: float, until: float | None) -> bool:
        if until is None or fraction < until:
            return False
        self.say(f"\n  explored {100 * fraction:.1f} % at sim time "
                 f"{self.log.sim_time - (self.log.ready_at or 0.0):.1f} s: stopping")
        return True

    def settled_enough(self, t: float, upto: float = math.inf) -> bool:
        """With --until-settled: whether the team has settled at sim time ``t`` [s], from the
        robots' states stamped up to ``upto`` [s]."""
        if self.settle is None or not self.settle.settled(self.log.H_samples, t, self.alive(),
                                                          upto):
            return False
        self.log.settled_at = t - (self.log.ready_at or 0.0)
        self.say(f"\n  settled: H within {100 * SETTLED_BAND:g} % and no robot moving between "
                 f"cells for {self.settle.window:g} s at sim time "
                 f"{self.log.settled_at:.1f} s: stopping")
        return True

    def team_ready(self, t0: float) -> None:
        """Every robot is up (``t0``: wall time the launcher began waiting)."""
        log = self.log
        log.ready_at = log.sim_time
        # Both anchors of the run's real-time factor are taken now, before the first cost
        # evaluation (which takes a while on big maps and would leave sim_start stale).
        log.wall_start = time.monotonic()
        log.sim_start = log.sim_time
        for sub in self.state_subs if self.settle is None else ():
            self.destroy_subscription(sub)
        self.say(f"  team ready at sim time {log.ready_at:.1f} s after "
                 f"{log.wall_start - t0:.1f} s wall")
        log.H_samples.append((log.ready_at, self.cost()))

    def check_children(self, starting: bool = False) -> None:
        """RuntimeError if the world or, while ``starting``, a robot exited; a robot that
        exits later is lost."""
        now = time.monotonic()
        if now - self._clock_checked >= 1.0:  # a graph query: once a second is enough
            self._clock_checked = now
            self.clock_error = self.clock_error or self.clock_guard.check_publishers(
                self.count_publishers("/clock"))
        if self.clock_error:
            raise RuntimeError(f"{self.clock_error}; stopping the team")
        if starting and now - self._stuck_checked >= STUCK_CHECK_PERIOD:
            self._stuck_checked = now
            self.procs.restart_stuck(self.say)
        world = self.procs.children.get("world")
        if world is not None and not world.alive:
            raise RuntimeError(f"world_node exited ({world.popen.returncode}):\n"
                               f"{self.procs.tail(world)}")
        for i in self.alive():
            child = self.procs.children.get(self.process_of.get(i, ""))
            if child is None or child.alive:
                continue
            if starting:
                raise RuntimeError(f"robot {i} exited during start-up "
                                   f"({child.popen.returncode}):\n{self.procs.tail(child)}")
            self.say(f"\n  robot {i} exited ({child.popen.returncode}):\n"
                     f"{self.procs.tail(child)}")
            self.log.lost[i] = self.log.sim_time

    def progress(self, final: bool = False) -> None:
        log = self.log
        ready, wall_start = log.ready_at, log.wall_start
        if self.config.quiet or ready is None or wall_start is None:
            return
        span = self.config.duration
        frac = min(1.0, max(0.0, (log.sim_time - ready) / span))
        wall = time.monotonic() - wall_start
        rtf = (log.sim_time - (log.sim_start or 0.0)) / wall if wall > 0 else 0.0
        H = log.H_samples[-1][1] if log.H_samples else math.nan
        bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
        explored = "" if self.exploration is None else \
            f"  explored {100 * self.exploration.explored:5.1f} %"
        line = (f"  [{bar}] sim {log.sim_time - ready:6.1f}/{span:g} s  rtf {rtf:4.2f}"
                f"  H {H:9.4g}  collisions {log.collisions}{explored}")
        if sys.stderr.isatty():
            print("\r" + line, end="\n" if final else "", file=sys.stderr, flush=True)
        elif final or int(frac * 10) != self._decile:
            self._decile = int(frac * 10)
            print(line, file=sys.stderr, flush=True)
