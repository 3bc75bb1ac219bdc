"""The hardware bridge's safety rules, as a pure state machine on an injected clock
(docs/hardware.md §Safety).

What a lab needs between a fleet of agents and real robots, every rule on wall-clock seconds
(the bridge's sim time is wall time since the start, so the scenario's watchdog reads the same):

* **Start gate**: no command goes to a robot before the mission's start.
* **Command watchdog**: a robot whose newest command is older than ``watchdog`` [s] is sent zero
  once, reported (``watchdog_stop``, as the simulator reports it), and held at zero until a new
  command comes.
* **Keep-alive**: the newest command (zero after a stop) is re-sent every ``1 / repeat_hz`` [s],
  so a 5 Hz LTL robot never trips a robot-side ``cmd_vel`` timeout shorter than 200 ms.
* **Tracking lost**: a rigid body without a pose for longer than ``lost_after`` [s] (or never
  seen ``lost_after`` after the start) halts *every* robot — collision avoidance needs every
  pose — with one ``tracking_lost`` event.
* **Geofence**: a robot whose pose leaves the arena grown by ``margin`` [m] halts every robot,
  with one ``geofence`` event.
* A halt is latched: every robot is held at zero (re-sent at its keep-alive rate) until the
  bridge ends; commands that come afterwards are counted, not sent. A person restarts the run.
* **Stop** (``Control(stop)``, SIGINT, SIGTERM, the end of the mission): zero to every robot.

The machine decides *what* to send; the bridge sends it (:class:`Send`, a tlfleet command:
world-frame ``(vx, vy, ω)`` for omni robots, ``(v, ω)`` for unicycles).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from tlfleet.agent.model import Robot, Scenario


@dataclass(frozen=True)
class Send:
    """Send ``u`` to ``robot`` now; ``why``: command | keepalive | watchdog | halt | stop."""

    robot: int
    u: tuple[float, ...]
    why: str


@dataclass(frozen=True)
class SafetyEvent:
    """A halt to report: ``kind`` ``tracking_lost`` or ``geofence``, with its data."""

    kind: str
    data: dict[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class SafetyConfig:
    """The rules' parameters (from the scenario's ``[sim] watchdog``, its arena and the lab)."""

    watchdog: float  # [s] no fresh command this long → zero + watchdog_stop
    lost_after: float  # [s] a rigid body without a pose this long → halt everybody
    fence: tuple[float, float, float, float]  # (xmin, xmax, ymin, ymax) [m] of the geofence
    repeat_period: Mapping[int, float]  # robot → [s] between keep-alive re-sends

    @classmethod
    def for_lab(cls, scenario: Scenario, lost_after: float, margin: float,
                repeat_hz: Mapping[int, float]) -> SafetyConfig:
        a = scenario.arena
        return cls(watchdog=scenario.sim.watchdog, lost_after=lost_after,
                   fence=(a.xmin - margin, a.xmax + margin, a.ymin - margin, a.ymax + margin),
                   repeat_period={r: 1.0 / hz for r, hz in repeat_hz.items()})


def zero(kind: str) -> tuple[float, ...]:
    return (0.0, 0.0, 0.0) if kind == "omni" else (0.0, 0.0)


def clip_command(robot: Robot, u: tuple[float, ...]) -> tuple[float, ...]:
    """``u`` clipped to the robot's velocity limits, as the simulator clips it: an omni robot's
    ‖(vx, vy)‖ ≤ max_lin and |ω| ≤ max_ang, a unicycle's |v| ≤ max_v and |ω| ≤ max_omega.
    ``ValueError`` for a command of the wrong length or with non-finite values."""
    expected = 3 if robot.kind == "omni" else 2
    if len(u) != expected:
        raise ValueError(f"robot {robot.id} ({robot.kind}) expects {expected} command values, "
                         f"got {len(u)}")
    if not all(math.isfinite(v) for v in u):
        raise ValueError(f"robot {robot.id}: non-finite command {tuple(u)!r}")
    if robot.kind == "omni":
        vx, vy, w = (float(v) for v in u)
        norm = math.hypot(vx, vy)
        if norm > robot.omni.max_lin:
            scale = robot.omni.max_lin / norm
            vx, vy = vx * scale, vy * scale
        return vx, vy, max(-robot.omni.max_ang, min(robot.omni.max_ang, w))
    v, w = (float(x) for x in u)
    lim = robot.unicycle
    return max(-lim.max_v, min(lim.max_v, v)), max(-lim.max_omega, min(lim.max_omega, w))


@dataclass
class _Robot:
    kind: str
    held: tuple[float, ...]  # what the keep-alive re-sends
    commanded_at: float | None = None  # [s] newest command forwarded
    sent_at: float = -math.inf  # [s] newest send of any kind
    stopped: bool = False  # the watchdog stopped it (until a new command)
    pose_at: float | None = None  # [s] newest pose
    pose: tuple[float, float, float] | None = None


class Safety:
    """The rules of the module docstring for one fleet. Not thread-safe: the bridge holds a
    lock around every call."""

    def __init__(self, config: SafetyConfig, kinds: Mapping[int, str]):
        self.config = config
        self.robots = {r: _Robot(kind, zero(kind)) for r, kind in sorted(kinds.items())}
        self.started_at: float | None = None
        self.halted: SafetyEvent | None = None  # the latched halt, once there is one
        self.ended = False
        self.dropped = {"before_start": 0, "halted": 0, "after_stop": 0}

    # ----------------------------------------------------------------- inputs

    def start(self, now: float) -> None:
        if self.started_at is None:
            self.started_at = now

    def pose(self, robot: int, x: float, y: float, yaw: float, now: float) -> None:
        """The newest pose of ``robot``'s rigid body (after the calibration offset)."""
        state = self.robots[robot]
        state.pose, state.pose_at = (x, y, yaw), now

    def command(self, robot: int, u: tuple[float, ...], now: float) -> list[Send]:
        """A fresh, checked command of ``robot``: what to send for it (nothing before the start,
        after a halt or after the stop: those are counted in ``dropped``)."""
        state = self.robots[robot]
        if self.ended:
            self.dropped["after_stop"] += 1
            return []
        if self.started_at is None:
            self.dropped["before_start"] += 1
            return []
        if self.halted is not None:
            self.dropped["halted"] += 1
            return []
        state.held, state.commanded_at, state.sent_at, state.stopped = u, now, now, False
        return [Send(robot, u, "command")]

    # ----------------------------------------------------------------- the clock

    def tick(self, now: float) -> tuple[list[Send], list[int], list[SafetyEvent]]:
        """Run the rules at ``now`` [s]: ``(sends, robots the watchdog stopped now, halts)``."""
        if self.started_at is None or self.ended:
            return [], [], []
        sends: list[Send] = []
        stopped: list[int] = []
        events: list[SafetyEvent] = []
        if self.halted is None:
            event = self._tracking(now) or self._geofence()
            if event is not None:
                self.halted = event
                events.append(event)
                for robot, state in self.robots.items():
                    state.held, state.sent_at = zero(state.kind), now
                    sends.append(Send(robot, state.held, "halt"))
                return sends, stopped, events
            for robot, state in self.robots.items():
                if (state.commanded_at is not None and not state.stopped
                        and now - state.commanded_at > self.config.watchdog + 1e-9):
                    state.stopped, state.held, state.sent_at = True, zero(state.kind), now
                    stopped.append(robot)
                    sends.append(Send(robot, state.held, "watchdog"))
        for robot, state in self.robots.items():
            if state.commanded_at is None and self.halted is None:
                continue  # never commanded: at rest, nothing to keep alive (as the simulator)
            if now - state.sent_at >= self.config.repeat_period[robot] - 1e-9:
                state.sent_at = now
                sends.append(Send(robot, state.held, "keepalive"))
        return sends, stopped, events

    def stop(self, now: float) -> list[Send]:
        """The end: zero to every robot (whether started or not); later commands are dropped."""
        self.ended = True
        sends = []
        for robot, state in self.robots.items():
            state.held, state.sent_at = zero(state.kind), now
            sends.append(Send(robot, state.held, "stop"))
        return sends

    # ----------------------------------------------------------------- rules

    def _tracking(self, now: float) -> SafetyEvent | None:
        assert self.started_at is not None
        lost = []
        for robot, state in self.robots.items():
            since = state.pose_at if state.pose_at is not None else self.started_at
            if now - since > self.config.lost_after + 1e-9:
                lost.append(robot)
        if not lost:
            return None
        ages = {str(r): (None if self.robots[r].pose_at is None
                         else round(now - self.robots[r].pose_at, 4)) for r in lost}
        return SafetyEvent("tracking_lost", {"robots": lost, "age": ages,
                                             "lost_after": self.config.lost_after})

    def _geofence(self) -> SafetyEvent | None:
        xmin, xmax, ymin, ymax = self.config.fence
        for robot, state in self.robots.items():
            if state.pose is None:
                continue
            x, y, _ = state.pose
            if not (xmin <= x <= xmax and ymin <= y <= ymax):
                return SafetyEvent("geofence", {"robot": robot, "x": round(x, 4),
                                                "y": round(y, 4), "fence": list(self.config.fence)})
        return None
