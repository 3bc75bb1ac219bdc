"""Real robots behind the simulator's world interface (docs/hardware.md §The bridge).

:class:`HardwareWorld` is what :class:`tlfleet.sim.process.SimProcess` drives when the bridge
takes the simulator's place: it answers ``mocap_poses()`` with each robot's newest motion-capture
pose (sample and hold; its ``poll``, the ROS link's, first hands it what came since), turns
commands into twists on the robots' topics through a :class:`RobotLink`, runs the safety rules of
:mod:`tlfleet.sim.hardware.safety` on every ``step`` (keep-alive, tracking lost, geofence) and
``check_watchdog`` (the command watchdog), and reports contacts from the poses: a robot–robot
contact begins when two discs of the scenario's radii overlap, a wall contact when a disc crosses
the arena's boundary or an obstacle.

Thread-safe: poses come through ``poll`` on the simulator loop's thread (or from whoever calls
``on_pose``), commands on a transport thread; one lock guards the state, and a send happens
under it (so the sends to one robot keep their order).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from tlfleet.agent.model import DiscObstacle, RectObstacle, Scenario
from tlfleet.agent.scenario.lab import Lab
from tlfleet.agent.scenario.rep103 import apply_offset, twist_of_command
from tlfleet.sim.hardware.safety import (
    Safety,
    SafetyConfig,
    SafetyEvent,
    Send,
    clip_command,
)
from tlfleet.sim.world import WALL, Contact

logger = logging.getLogger(__name__)


class RobotLink(Protocol):
    """Where twists go: ``send(robot, (linear.x, linear.y, angular.z))`` in the robot's body
    frame [m/s, m/s, rad/s] (:class:`tlfleet.sim.hardware.ros_link.RosLink` for real)."""

    def send(self, robot: int, twist: tuple[float, float, float]) -> None: ...


@dataclass
class _Commanded:
    """What :meth:`SimProcess._report_step` reads of a robot (``last_command_t``, sim time)."""

    last_command_t: float | None = None


class HardwareWorld:
    """The fleet's real robots (see the module docstring). ``now``: the monotonic wall clock."""

    def __init__(self, scenario: Scenario, lab: Lab, link: RobotLink | None = None,
                 now: Callable[[], float] = time.monotonic,
                 poll: Callable[[], object] | None = None):
        self.scenario = scenario
        self.lab = lab
        self.link = link
        # called (outside the lock) before the poses are read: hands what came since to
        # on_pose (RosLink.poll); None when the poses are pushed to on_pose
        self.poll = poll
        self._polled_at = -math.inf  # [s] when poll was last asked
        # [s] the safety rules poll again when the loop's last poll (for a frame) is older: 1.5
        # frame periods (a loop late for its frame), well within the lost limit
        self.poll_fresh = min(1.5 / scenario.sim.mocap_rate, 0.25 * lab.lost_after)
        self._now = now
        self._lock = threading.Lock()
        self.ids = sorted(r.id for r in scenario.robots)
        self._spec = {r.id: r for r in scenario.robots}
        self._offset = {r.id: lab.robot(r.id).pose_offset for r in scenario.robots}
        self.watchdog = scenario.sim.watchdog  # [s]
        self.safety = Safety(
            SafetyConfig.for_lab(scenario, lab.lost_after, lab.geofence_margin,
                                 {r.id: r.repeat_hz for r in lab.robots}),
            {r.id: r.kind for r in scenario.robots})
        self.robots = {r: _Commanded() for r in self.ids}
        self._poses: dict[int, tuple[float, float, float]] = {}
        self._events: list[SafetyEvent] = []
        self._stopped: list[int] = []  # robots the watchdog stopped, not reported yet
        self._touching: set[tuple[int, int | str, str]] = set()
        self._contacts: list[Contact] = []
        self.t0: float | None = None  # [s] wall time of the mission's start
        self.sent = 0  # twists sent
        self.sends_by_reason: dict[str, int] = {}

    # ----------------------------------------------------------------- poses (ROS thread)

    def on_pose(self, robot: int, x: float, y: float, yaw: float) -> None:
        """A rigid body's pose ``(x, y, yaw)`` [m, m, rad] in the world frame."""
        pose = apply_offset(x, y, yaw, self._offset[robot])
        now = self._now()
        with self._lock:
            self._poses[robot] = pose
            self.safety.pose(robot, *pose, now)

    def _poll(self, unless_within: float = 0.0) -> None:
        """Ask ``poll`` for what came since, unless it was asked less than ``unless_within``
        [s] ago."""
        if self.poll is None:
            return
        now = self._now()
        if now - self._polled_at >= unless_within:
            self._polled_at = now
            self.poll()

    def missing_poses(self) -> list[int]:
        self._poll()
        with self._lock:
            return [r for r in self.ids if r not in self._poses]

    def mocap_poses(self) -> tuple[tuple[int, float, float, float], ...]:
        """Every robot's newest pose, ``(id, x, y, θ)`` by id (a robot never seen: NaN, which
        the bridge never publishes: it waits for every body before it starts)."""
        self._poll()
        with self._lock:
            poses = dict(self._poses)
        nan = (math.nan, math.nan, math.nan)
        return tuple((r, *poses.get(r, nan)) for r in self.ids)

    # ----------------------------------------------------------------- commands

    def check_command(self, robot: int, u: tuple[float, ...]) -> tuple[float, ...]:
        """``u`` clipped to the robot's limits; ``ValueError`` for a command the robot cannot
        take (length, non-finite)."""
        return clip_command(self._spec[robot], u)

    def start(self) -> None:
        """The mission starts now: commands may go out from here on."""
        now = self._now()
        with self._lock:
            self.t0 = now
            self.safety.start(now)

    def command(self, robot: int, u: tuple[float, ...], *, clipped: bool = False) -> bool:
        """Forward a fresh, checked command at once (clipped to the robot's limits, unless
        ``clipped`` says :meth:`check_command` did); False when the safety rules hold it back
        (before the start, after a halt or the stop)."""
        if not clipped:
            u = clip_command(self._spec[robot], u)
        now = self._now()
        with self._lock:
            sends = self.safety.command(robot, u, now)
            if sends and self.t0 is not None:
                self.robots[robot].last_command_t = now - self.t0
            self._send(sends)
        return bool(sends)

    def set_command(self, robot: int, u: tuple[float, ...], t: float) -> None:
        """The simulator loop's apply step: the bridge already forwarded the command when it
        came (:meth:`command`), so nothing is left to do."""

    # ----------------------------------------------------------------- the loop's clock

    def check_watchdog(self, t: float) -> list[int]:
        """Run the safety rules now; the robots the command watchdog stopped since the last
        call (by this or by :meth:`step`)."""
        self._tick()
        with self._lock:
            stopped, self._stopped = self._stopped, []
        return stopped

    def step(self, duration: float, *, draw_disturbance: bool = True) -> None:
        """Time passes by itself; run the rules (keep-alive, tracking, geofence)."""
        self._tick()

    def _tick(self) -> None:
        # the loop polled for its frame just before, unless it stalled since: then the rules
        # must judge the bodies on what came meanwhile, not call them lost
        self._poll(unless_within=self.poll_fresh)
        now = self._now()
        with self._lock:
            sends, stopped, events = self.safety.tick(now)
            self._send(sends)
            self._stopped.extend(stopped)
            self._events.extend(events)
            self._find_contacts()
        for event in events:
            logger.error("%s: every robot held at zero for the rest of the run (%s)",
                         event.kind, event.data)

    def stop_all(self, repeats: int = 1) -> None:
        """Zero to every robot, ``repeats`` times; no command goes out afterwards."""
        now = self._now()
        with self._lock:
            sends = self.safety.stop(now)
            for _ in range(max(1, repeats)):
                self._send(sends)

    def drain_events(self) -> list[SafetyEvent]:
        with self._lock:
            events, self._events = self._events, []
        return events

    def drain_contacts(self) -> list[Contact]:
        with self._lock:
            contacts, self._contacts = self._contacts, []
        return contacts

    # ----------------------------------------------------------------- inside the lock

    def _send(self, sends: list[Send]) -> None:
        if self.link is None:
            return
        for send in sends:
            yaw = self._poses.get(send.robot, (0.0, 0.0, 0.0))[2]
            twist = twist_of_command(self._spec[send.robot].kind, send.u, yaw)
            try:
                self.link.send(send.robot, twist)
            except Exception:  # a failed send must not take the loop or a callback down
                logger.exception("sending %s to robot %d failed", send.why, send.robot)
                continue
            self.sent += 1
            self.sends_by_reason[send.why] = self.sends_by_reason.get(send.why, 0) + 1

    def _find_contacts(self) -> None:
        """Contact onsets from the newest poses (a pair touching since the last look is not
        reported again)."""
        touching: set[tuple[int, int | str, str]] = set()
        poses = self._poses
        arena = self.scenario.arena
        ids = [r for r in self.ids if r in poses]
        for i, a in enumerate(ids):
            xa, ya, _ = poses[a]
            ra = self._spec[a].radius
            for b in ids[i + 1:]:
                xb, yb, _ = poses[b]
                if math.hypot(xa - xb, ya - yb) < ra + self._spec[b].radius:
                    touching.add((a, b, ""))
            if (xa - ra < arena.xmin or xa + ra > arena.xmax or ya - ra < arena.ymin
                    or ya + ra > arena.ymax):
                touching.add((a, WALL, "arena"))
            for k, obstacle in enumerate(arena.obstacles):
                if _touches(obstacle, xa, ya, ra):
                    touching.add((a, WALL, f"obstacle:{obstacle.name or k}"))
        for a, b, what in sorted(touching - self._touching, key=str):
            self._contacts.append(Contact(a, b, what))
        self._touching = touching


def _touches(obstacle: object, x: float, y: float, r: float) -> bool:
    """A disc at ``(x, y)`` of radius ``r`` [m] overlaps ``obstacle``."""
    if isinstance(obstacle, DiscObstacle):
        cx, cy = obstacle.center
        return math.hypot(x - cx, y - cy) < r + obstacle.radius
    if isinstance(obstacle, RectObstacle):
        dx = max(obstacle.xmin - x, 0.0, x - obstacle.xmax)
        dy = max(obstacle.ymin - y, 0.0, y - obstacle.ymax)
        return math.hypot(dx, dy) < r
    return False
