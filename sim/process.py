"""The simulator process: the pymunk world behind the tlfleet protocol (architecture.md §1–§3).

One loop on the main thread owns the :class:`~tlfleet.sim.world.World` and every piece of state. The
transport's callbacks only put ``(kind, key, payload)`` on a queue (stack-notes.md §0: keep
callbacks tiny); the loop decodes, decides and publishes. In lockstep the commands come through a
channel the loop reads itself (``Transport.subscribe_channel``). Each frame goes out on
``mocap`` and on ``mocap_every/<d>/<φ>`` for the fleet's control schedules (d ≥ 2, φ) with
``seq % d == φ`` and on ``mocap_at/<s>`` for the every-tick robots' frame offsets s ≥ 1; in
realtime with spread frames those keys carry frames sampled at their offsets instead.

Protocol (architecture.md §3 and the issue-5 contract):

* before ``Control(start)``: the initial ``MocapFrame(t=0, seq=0, due=())`` every
  ``preview_period`` wall seconds, so agents can initialise;
* tick k after start, t_k = k / mocap_rate: ``MocapFrame(t_k, k, poses, due)`` then
  ``Clock(t_k, k, mode)`` (the frame first: the lockstep fleet waits for it);
  - **lockstep**: before tick 0 the loop waits (at most ``tick_timeout``) until it has seen
    every robot's agent alive; ``due`` = the live agents' robots due at k
    (:func:`tlfleet.sim.lockstep.due_robots`); the loop waits for their ``Command(seq=k)`` (wall
    timeout ``tick_timeout`` → one ``deadline_miss`` event per missing robot; a dead agent is
    dropped at once), applies them, then steps the physics by one mocap period;
  - **realtime**: ``due = ()``; the loop steps the physics once per mocap period of wall time
    (:class:`tlfleet.sim.clock.Pacer`) with the newest command of each robot; control deadlines
    count from tick 1 (tick 0 looks like the preview frame, which agents do not answer); with
    ``SimParams.spread_frames`` (default) each robot's frames are sampled at its offset s_r
    (``Scenario.frame_offset``): the tick frame goes on ``mocap`` only, and at each offset s ≥ 1
    of the period the loop applies the commands that came so far, steps the physics to
    t_k + s·dt and publishes ``MocapFrame(t_k + s·dt, k, poses, ())`` on ``mocap_at/s`` and
    on the due ``mocap_every`` keys of that offset; at t_{k+1} it finishes the period. Robot
    r's deadline for tick k is then t_{k+1} + s_r·dt (architecture.md §3);
* after every step: ``watchdog_stop`` and ``contact`` events, stamped t_k and t_{k+1}; they are
  published after the next frame (:meth:`SimProcess._report_step`);
* at t = ``duration``: the final frame (``due = ()``), ``Event(kind="sim_stats")`` (counters,
  frame → command latency, missed control deadlines: :meth:`SimProcess.summary`), then
  ``Event(kind="sim_done")``, exit 0. ``Control(stop)``, SIGINT or SIGTERM end the loop earlier
  (``sim_stats`` only), also with 0.

A ``seq = 0`` command that arrives before the sim has processed the start is an agent's answer
to a republished initial frame and is held for tick 0 (``tlfleet.sim.lockstep``, "early answers").

Commands have an age (:mod:`tlfleet.sim.command_age`): in realtime a command older than
its robot's bound (``SimConfig.max_command_age``; default 5 control periods) is not applied, counted
in
``sim_stats`` (``stale_commands``) and reported once per episode as ``Event(stale_command)``; the
watchdog then stops the robot. A decoded command outside the fleet's bounds
(:class:`tlfleet.bus.protocol.bounds.FleetBounds`: time/seq disagreement, speeds far above the
robot's limits) is treated like a malformed one.

Backfill (:mod:`tlfleet.sim.frame_ring`): every tick's frame is also kept, as published,
in a ring of the last ``backfill_seconds`` of frames (bounded in bytes too), and the queryable
``sim/backfill`` answers a recorder's ``BackfillRequest`` with the frames it missed while a link
was cut. The handler runs on a zenoh thread and touches only the ring (thread-safe); a request
that does not decode is counted as malformed like any payload. The ring's counters are in
``sim_stats`` (``backfill``).

A payload that does not decode (or a command whose key, robot or values do not fit) is counted,
logged at most once per ``malformed_report_period`` per key, and published as
``Event(kind="malformed_message", data={"key", "count"})``; it never stops the process.
"""

from __future__ import annotations

import logging
import queue
import sys
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tlfleet.agent.model import Scenario
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.lifeline import ORPHAN_AFTER, CoordinatorWatch
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.bounds import FleetBounds
from tlfleet.bus.protocol.codec import ProtocolError, decode, encode
from tlfleet.bus.protocol.messages import (
    BackfillRequest,
    Clock,
    Command,
    Control,
    Event,
    MocapFrame,
    TimeMode,
)
from tlfleet.bus.signals import install_signal_handlers
from tlfleet.bus.transport import Channel, Closeable, Transport, TransportConfig
from tlfleet.bus.zenoh.transport import open_transport
from tlfleet.sim.clock import Pacer, TickClock
from tlfleet.sim.command_age import CommandAge
from tlfleet.sim.frame_ring import BACKFILL_BYTES, BACKFILL_SECONDS, FrameRing, ring_size
from tlfleet.sim.lockstep import (
    LatestCommands,
    LockstepCollector,
    Offer,
    control_dividers,
    control_phases,
    due_robots,
)
from tlfleet.sim.stats import TimingStats
from tlfleet.sim.world import WALL, World, WorldConfig, native_tracking_available

logger = logging.getLogger(__name__)

SOURCE = "sim"
MAX_MALFORMED_KEYS = 64  # distinct keys counted apart in sim_stats' malformed_by_key
OTHER_KEYS = "(other keys)"
LINGER = 0.1  # [s] wall between the last publication and closing the session
SWITCH_INTERVAL = 0.0005  # [s] GIL switch interval: callbacks not held ~5 ms (stack-notes §2.3)


class SimConfigError(TlfleetError, ValueError):
    """A simulator setting out of range (names the setting and the value)."""


@dataclass(frozen=True)
class SimConfig:
    """How one simulator process runs (the CLI flags of ``tlfleet sim``)."""

    mode: TimeMode = "lockstep"
    duration: float = 60.0  # [s] sim time of the run
    seed: int = 0  # seed of the one numpy Generator (disturbance, mocap noise)
    tick_timeout: float = 2.0  # [s] wall: lockstep wait for the due commands of one tick
    preview_period: float = 0.1  # [s] wall between initial frames before start
    malformed_report_period: float = 1.0  # [s] wall between reports of one key's malformed count
    poll: float = 0.05  # [s] wall: longest wait before the stop flag is checked again
    max_command_age: float | None = None  # [s] sim time; None: 5 control periods per robot
    max_speed: float | None = None  # lockstep: sim time runs at most this × wall time (None: free)
    backfill_seconds: float = BACKFILL_SECONDS  # [s] sim time of frames kept for the backfill
    backfill_bytes: int = BACKFILL_BYTES  # payload bytes the backfill ring holds at most
    world: WorldConfig = field(default_factory=WorldConfig)

    def __post_init__(self) -> None:
        if self.mode not in ("lockstep", "realtime"):
            raise SimConfigError(f"mode {self.mode!r}: expected 'lockstep' or 'realtime'")
        for name in ("duration", "tick_timeout", "preview_period", "poll"):
            value = getattr(self, name)
            if not (value >= 0.0 if name == "duration" else value > 0.0):
                raise SimConfigError(f"{name} = {value!r} s: must be "
                                     f"{'≥ 0' if name == 'duration' else '> 0'}")
        if not (self.backfill_seconds >= 0.0 and self.backfill_seconds < float("inf")):
            raise SimConfigError(f"backfill_seconds = {self.backfill_seconds!r} s: must be a "
                                 f"finite number ≥ 0")
        if self.backfill_bytes < 1:
            raise SimConfigError(f"backfill_bytes = {self.backfill_bytes!r}: must be ≥ 1")
        if self.max_speed is not None and not self.max_speed > 0.0:
            raise SimConfigError(f"max_speed = {self.max_speed!r}: must be > 0 (a factor of "
                                 f"wall-clock time)")

    @classmethod
    def for_scenario(cls, scenario: Scenario, *, mode: TimeMode = "lockstep",
                     duration: float | None = None, seed: int | None = None,
                     tick_timeout: float = 2.0, max_command_age: float | None = None,
                     max_speed: float | None = None,
                     backfill_seconds: float = BACKFILL_SECONDS) -> SimConfig:
        """The settings of a run of ``scenario``: duration and seed default to the scenario's."""
        return cls(mode=mode, duration=scenario.duration if duration is None else duration,
                   seed=scenario.sim.seed if seed is None else seed, tick_timeout=tick_timeout,
                   max_command_age=max_command_age, max_speed=max_speed,
                   backfill_seconds=backfill_seconds)


@dataclass(frozen=True)
class SimProcessConfig:
    """What ``tlfleet sim`` gives :func:`main`: the scenario file, the run's overrides and the
    transport (style.md §6)."""

    scenario: Path
    mode: TimeMode = "lockstep"
    duration: float | None = None  # [s] sim time; None: the scenario's
    seed: int | None = None  # None: the scenario's
    tick_timeout: float = 2.0  # [s] wall
    transport: TransportConfig = field(default_factory=TransportConfig)
    max_command_age: float | None = None  # [s] sim time (None: 5 control periods)
    max_speed: float | None = None  # lockstep: at most this × wall-clock time (None: free)
    backfill_seconds: float = BACKFILL_SECONDS  # [s] sim time of frames kept for the backfill
    orphan_after: float = ORPHAN_AFTER  # [s] wall: exit once the coordinator is gone this long


@dataclass
class SimStats:
    """What the loop counted; logged at the end and handy in tests."""

    ticks: int = 0
    deadline_misses: int = 0
    contacts: int = 0
    watchdog_stops: int = 0
    overruns: int = 0
    wall_time: float = 0.0  # [s] from start to the end of the loop


class SimProcess:
    """The simulator's loop on one transport (see the module docstring).

    ``now`` is the monotonic wall clock (injectable for tests). ``stop`` ends the loop when set
    (SIGINT/SIGTERM handlers set it in :func:`main`).
    """

    def __init__(self, transport: Transport, scenario: Scenario, config: SimConfig,
                 stop: threading.Event | None = None,
                 now: Callable[[], float] = time.monotonic, world: Any = None):
        self.transport = transport
        self.scenario = scenario
        self.config = config
        self.stop_event = stop or threading.Event()
        self._now = now
        self.fleet = scenario.fleet
        # ``world``: what stands in for the pymunk world (the hardware bridge's robots,
        # tlfleet.sim.hardware): the same interface, the same frames, keys and events
        self.world = world if world is not None else World.from_scenario(
            scenario, np.random.default_rng(config.seed), config.world)
        if world is not None:
            logger.info("world: %s", type(world).__name__)
        elif self.world.config.native_tracking:
            logger.info("tracking law: C (tlfleet.sim._tracking)")
        elif native_tracking_available():
            logger.info("tracking law: Python (tracking = %r)", self.world.config.tracking)
        else:
            logger.warning("the C tracking law (tlfleet.sim._tracking) was not built at install "
                           "time (no C compiler?): running the Python law, the same results, "
                           "about 3x slower physics")
        self.clock = TickClock(scenario.sim.mocap_rate)
        self.dividers = control_dividers(scenario)
        self.phases = control_phases(scenario)
        # (divider, phase) of each robot with divider ≥ 2: the ticks it is due on are shared
        self._slow_schedules = tuple((d, self.phases.get(r, 0))
                                     for r, d in sorted(self.dividers.items()) if d > 1)
        schedules = keys.frame_schedules((d, self.phases[r]) for r, d in self.dividers.items())
        self._every = tuple((d, p, keys.mocap_every(scenario.fleet, d, p)) for d, p in schedules)
        # frame offsets (Scenario.frame_offset, architecture.md §3): in realtime each robot's
        # frames are sampled its offset s_r of physics steps after the tick; lockstep publishes
        # the tick's frame on every key
        self.offsets = {r.id: scenario.frame_offset(r.id) for r in scenario.robots}
        self._step = self.clock.period / scenario.substeps_per_tick  # [s] sim time per step
        self._at = {s: keys.mocap_at(scenario.fleet, s) for s in scenario.every_tick_offsets()}
        # the slots of a period in which no robot with divider ≥ 2 is due (most of them)
        self._at_slots = [(s, (key,)) for s, key in self._at.items()]
        self._every_offset = max((s for r, s in self.offsets.items()
                                  if self.dividers.get(r, 1) > 1), default=0)
        self._spread = config.mode == "realtime" and any(self.offsets.values())
        self.ages = CommandAge(self.dividers, scenario.sim.mocap_rate,
                               max_age=config.max_command_age)
        a = scenario.arena
        self.bounds = FleetBounds((a.xmin, a.xmax, a.ymin, a.ymax), config.duration,
                                  scenario.sim.mocap_rate, scenario.speed_limits())
        self.ring = FrameRing(ring_size(config.backfill_seconds, scenario.sim.mocap_rate),
                              config.backfill_bytes)
        self.lockstep = LockstepCollector(self.world.ids)
        self.latest = LatestCommands(self.world.ids)
        self.alive: set[int] = set()
        self.started = False
        self.stop_requested = False
        self.done = False  # sim time reached the duration
        self.t = 0.0  # [s] sim time of the newest frame
        self._frame0: tuple[tuple[int, float, float, float], ...] = ()  # the initial poses
        self.stats = SimStats()
        self.malformed: Counter[str] = Counter()
        self._reported: dict[str, tuple[int, float]] = {}  # key -> (count reported, wall time)
        self.timing = TimingStats(shared=self._shared_tick,
                                  every_tick=[r for r, d in self.dividers.items() if d == 1])
        # (kind, key, payload or liveliness, arrival wall time [s]) from the transport callbacks
        self._inbox: queue.SimpleQueue[tuple[str, str, Any, float]] = queue.SimpleQueue()
        self._cmds: Channel | None = None  # lockstep: the commands' channel
        self._keys = {"mocap": keys.mocap(self.fleet), "clock": keys.clock(self.fleet),
                      "event": keys.event(self.fleet, "sim", 0),
                      "backfill": keys.sim_backfill(self.fleet)}
        # robot of each command key of the fleet, parsed once (any other key: keys.robot_of)
        self._cmd_robot = {keys.cmd(self.fleet, robot): robot for robot in self.world.ids}
        # the last step's tick, due robots and watchdog stops, reported after the next frame
        self._unreported: tuple[int, tuple[int, ...], list[int]] | None = None
        # realtime with spread frames: physics steps of the current period already taken, the
        # watchdog's stops at its tick, and the deadlines still open, as (sim time [s] of the
        # pump that closes them, tick, robots): robot r's command for tick k must come before
        # the sim steps past t_{k+1} + s_r·dt
        self._stepped = 0
        self._tick_stops: list[int] = []
        self._deadlines: deque[tuple[float, int, tuple[int, ...]]] = deque()

    # ----------------------------------------------------------------- public

    def run(self) -> int:
        """Declare presence, subscribe, run until done or stopped; undeclare. Returns 0."""
        handles: list[Closeable] = []
        try:
            inbox = self._inbox
            wake = self._open_command_channel(handles)
            if self._cmds is None:
                handles.append(self.transport.subscribe(keys.all_cmds(self.fleet),
                                                        self._command_sample))
            handles.append(self.transport.subscribe(
                keys.control(self.fleet), lambda k, p: (inbox.put(("control", k, p, 0.0)),
                                                        wake())))
            handles.append(self.transport.watch_alive(
                keys.all_alive(self.fleet), lambda k, up: (inbox.put(("alive", k, up, 0.0)),
                                                           wake())))
            handles.append(self.transport.serve(self._keys["backfill"], self._on_backfill))
            handles.append(self.transport.declare_alive(keys.alive(self.fleet, "sim", 0)))
            logger.info("sim %s: %d robots, %s mode, seed %d, duration %g s", self.fleet,
                        len(self.world.ids), self.config.mode, self.config.seed,
                        self.config.duration)
            if self._wait_for_start():
                started = self._now()
                if self.config.mode == "lockstep":
                    self._run_lockstep()
                else:
                    self._run_realtime()
                self.stats.wall_time = self._now() - started
                self._report_step()  # a stop between a step and the next frame
            self._report_malformed(force=True)
            summary = self.summary()  # once: at fleet scale it is not free (stats._split)
            if self.started:
                self._event("sim_stats", **summary)
            if self.done:
                self._event("sim_done", ticks=self.stats.ticks)
            self._log_summary(summary)
            return 0
        finally:
            for handle in reversed(handles):
                try:
                    handle.close()
                except Exception:
                    logger.exception("undeclaring a sim entity failed")

    def _open_command_channel(self, handles: list[Closeable]) -> Callable[[], None]:
        """Lockstep: the commands come through a channel read by this loop's thread
        (``Transport.subscribe_channel``, when the transport has one), so a command wakes the
        loop directly; the loop is blocked waiting for them, so the arrival time it stamps is
        the arrival. Realtime keeps the callback, which stamps arrivals while the loop sleeps
        through the period. Returns what wakes the channel (a no-op without one)."""
        subscribe_channel = getattr(self.transport, "subscribe_channel", None)
        if self.config.mode != "lockstep" or subscribe_channel is None or not self.world.ids:
            return lambda: None
        # the wake-up is session-local: it reaches only this subscriber, never an agent
        self._cmds = subscribe_channel(keys.all_cmds(self.fleet),
                                       wake_key=keys.cmd(self.fleet, self.world.ids[0]))
        handles.append(self._cmds)
        return self._cmds.wake

    def _command_sample(self, key: str, payload: bytes) -> None:
        """A command's sample (on a transport thread, realtime): queued for the loop with its
        arrival time."""
        self._inbox.put(("cmd", key, payload, self._now()))

    @property
    def stopping(self) -> bool:
        return self.stop_requested or self.stop_event.is_set()

    # ----------------------------------------------------------------- phases

    def _wait_for_start(self) -> bool:
        """Publish the initial frame every ``preview_period`` until ``Control(start)``."""
        self._frame0 = self.world.mocap_poses()  # noise drawn once: start time stays irrelevant
        logger.info("sim: waiting for start from a coordinator on %s (tlfleet run or "
                    "tlfleet supervise)", keys.control(self.fleet))
        next_publish = self._now()
        while not self.stopping:
            if self._now() >= next_publish:
                self._publish_frame(MocapFrame(0.0, 0, self._frame0, ()))
                next_publish += self.config.preview_period
            self._pump(max(0.0, min(next_publish - self._now(), self.config.poll)))
            if self.started:
                return True
        return False

    def _run_lockstep(self) -> None:
        """Tick k waits for the due robots' ``Command(seq=k)``; with ``max_speed`` it also waits
        until wall time has caught up with sim time / max_speed (pacing only adds waits, so the
        trajectory is the same as unpaced)."""
        last = self.clock.last_tick(self.config.duration)
        speed = self.config.max_speed
        pacer = Pacer(self.clock.period / speed, self._now) if speed is not None else None
        self._await_agents()
        k = 0
        while not self.stopping:
            if pacer is not None and k > 0:
                # wait on the stop event, not on the command channel: a zenoh channel's recv
                # may time out up to its timer's tick late (tlfleet.bus.transport.CHANNEL_TICK, 50
                # ms; waiting on the channel made every paced tick last ≈ 45 ms: a 10 s run at
                # --max-speed 2 took 49 s); no command can come before the tick it
                # answers is published
                while not self.stopping and (left := pacer.remaining()) > 0.0:
                    self._pump(0.0)
                    self.stop_event.wait(min(left, self.config.poll))
                pacer.advance()
            due = () if k >= last else due_robots(k, self.dividers, self.alive, self.phases)
            self._publish_tick(k, due)
            if k >= last:
                self._finish()
                return
            for robot in self.lockstep.begin(k, due):
                self.timing.answered(robot, k)
            self._pump(0.0)
            deadline = self._now() + self.config.tick_timeout
            while not self.lockstep.complete and not self.stopping:
                left = deadline - self._now()
                if left <= 0.0:
                    for robot in self.lockstep.expire():
                        self.stats.deadline_misses += 1
                        logger.warning("robot %d missed the deadline of tick %d", robot, k)
                        self._event("deadline_miss", robot=robot, seq=k)
                    break
                self._pump(min(left, self.config.poll))
            if self.stopping:
                return
            answering = tuple(r for r in self.lockstep.due if r in self.alive)
            self._advance(k, self.lockstep.take(), answering)
            k += 1

    def _await_agents(self) -> None:
        """Lockstep, before tick 0: wait (at most ``tick_timeout`` wall) until the liveliness
        token of every robot's agent has been seen. The coordinator starts the mission once it
        has seen them all, but over peer links (architecture.md §1) the token may reach the sim
        by another path than the start, and later: a robot left out of tick 0's ``due`` would
        not move at t = 0 and the run would differ from the same run through the router."""
        expected = set(self.world.ids)
        deadline = self._now() + self.config.tick_timeout
        while not self.stopping and not expected <= self.alive:
            left = deadline - self._now()
            if left <= 0.0:
                logger.warning("lockstep: starting without the agents of robots %s (no "
                               "liveliness token within %g s)", sorted(expected - self.alive),
                               self.config.tick_timeout)
                return
            self._pump(min(left, self.config.poll))

    def _run_realtime(self) -> None:
        last = self.clock.last_tick(self.config.duration)
        pacer = Pacer(self.clock.period, self._now)
        self.latest.started = True
        k = 0
        while not self.stopping:
            self._publish_tick(k, ())
            if k >= last:
                self._finish()
                break
            for offset, frame_keys in self._sub_ticks(k):  # spread frames (SimParams)
                self._sleep(pacer, self.clock.period - offset * self._step)
                self._pump(0.0)
                if self.stopping:
                    break
                self._close_deadlines(self.clock.time(k) + offset * self._step)
                self._advance_part(k, offset, self.latest.take())
                self._publish_sub_frame(k, offset, frame_keys)
            if self.stopping:
                break
            # Commands only take effect at the loop's next wake-up (the tick, or a spread frame's
            # slot) and their arrival is stamped in the transport callback, so the loop sleeps
            # until then and takes them all at once: one wake-up per tick and slot instead of one
            # per command (30 robots: 3000 a second).
            self._sleep(pacer, 0.0)
            self._pump(0.0)
            if self.stopping:
                break
            self._close_deadlines(self.clock.time(k + 1))
            pacer.advance()
            # Tick 0 owes no command: its frame (t = 0, seq = 0, due = ()) cannot be told from
            # the preview frame, which agents never answer (tlfleet.agent.runtime.loop), so counting
            # it would charge every robot one missed deadline per run.
            due = due_robots(k, self.dividers, self.alive, self.phases) if k > 0 else ()
            self._advance(k, self.latest.take(), due)
            k += 1
        self.stats.overruns = pacer.overruns

    def _sleep(self, pacer: Pacer, until_left: float) -> None:
        """Wait until ``until_left`` [s] of the pacer's period are left (or a stop)."""
        while not self.stopping and (left := pacer.remaining() - until_left) > 0.0:
            self.stop_event.wait(min(left, self.config.poll))

    def _sub_ticks(self, k: int) -> list[tuple[int, tuple[str, ...]]]:
        """Realtime with spread frames: (offset s ≥ 1 [physics steps], keys) of every frame of
        period k sampled after its tick, in time order: each ``mocap_at/s`` and the due
        ``mocap_every`` keys (at their schedules' offset). Empty without spread frames."""
        if not self._spread:
            return []
        due = [key for divider, phase, key in self._every if k % divider == phase]
        if not due:
            return self._at_slots
        groups: dict[int, list[str]] = {s: [key] for s, key in self._at.items()}
        groups.setdefault(self._every_offset, []).extend(due)
        return sorted((s, tuple(frame_keys)) for s, frame_keys in groups.items())

    def _close_deadlines(self, t: float) -> None:
        """Count the misses of the open deadlines that close at or before sim time ``t`` [s]
        (spread frames: ``_deadlines``)."""
        while self._deadlines and self._deadlines[0][0] <= t + 1e-9:
            _, k, robots = self._deadlines.popleft()
            for robot in self.timing.close_tick(k, robots):
                logger.debug("robot %d missed the deadline of tick %d", robot, k)

    # ----------------------------------------------------------------- one tick

    def _publish_tick(self, k: int, due: tuple[int, ...]) -> None:
        """Tick k's output, the frame first (architecture.md §3): in lockstep the whole
        fleet waits for it, so between the last due command and the frame the loop does only
        what the frame needs (:meth:`_advance`, the poses, the encoding, the puts). The clock,
        the frame's entry in the backfill ring and the report of the step that led here
        (:meth:`_report_step`) follow while the agents compute. The latency clock starts just
        before the frame's first put."""
        self.t = self.clock.time(k)
        poses = self._frame0 if k == 0 else self.world.mocap_poses()
        payload, published = self._publish_frame(MocapFrame(self.t, k, poses, due),
                                                 schedules=not self._spread)
        self._publish(self._keys["clock"], Clock(self.t, k, self.config.mode))
        self.timing.frame_published(k, published)
        self.ring.append(k, payload)
        self._report_step()

    def _advance(self, k: int, commands: list[Command], due: tuple[int, ...]) -> None:
        """Apply tick k's commands, run the watchdog, step the physics to t_{k+1}.

        ``due``: the live robots that owed a command for tick k. Their deadline bookkeeping and
        the watchdog's and the contacts' events wait for :meth:`_report_step`, after the next
        frame (off the lockstep round trip). After :meth:`_advance_part` (spread
        frames) the commands are applied from where that left off, and the rest of the period is
        stepped with the same disturbance; the robots due at an offset s ≥ 1 have their deadline
        at t_{k+1} + s·dt instead (``_deadlines``).
        """
        t = self.clock.time(k)
        if self._stepped:
            stopped, self._tick_stops = self._tick_stops, []
            self._apply(commands, t + self._stepped * self._step)
            self.world.step(self.clock.period - self._stepped * self._step,
                            draw_disturbance=False)
            self._stepped = 0
        else:
            self._apply(commands, t)
            stopped = self.world.check_watchdog(t)
            self.world.step(self.clock.period)
        if self._spread and due:
            later: dict[int, list[int]] = {}
            for robot in due:
                later.setdefault(self.offsets.get(robot, 0), []).append(robot)
            due = tuple(later.pop(0, ()))
            t_next = self.clock.time(k + 1)
            self._deadlines.extend((t_next + s * self._step, k, tuple(robots))
                                   for s, robots in sorted(later.items()))
        self.stats.ticks = k + 1
        self.t = self.clock.time(k + 1)
        self._unreported = (k, due, stopped)

    def _advance_part(self, k: int, offset: int, commands: list[Command]) -> None:
        """Spread frames, period k: apply the commands that came since the last part (from where
        it ended; the first part also runs the watchdog at t_k and draws the disturbance) and
        step the physics to t_k + ``offset``·dt; :meth:`_advance` finishes the period."""
        t = self.clock.time(k)
        first = self._stepped == 0
        self._apply(commands, t + self._stepped * self._step)
        if first:
            self._tick_stops = self.world.check_watchdog(t)
        self.world.step((offset - self._stepped) * self._step, draw_disturbance=first)
        self._stepped = offset

    def _apply(self, commands: list[Command], t: float) -> None:
        """Set the commands (realtime: the fresh ones, :mod:`tlfleet.sim.command_age`) from sim time
        ``t`` [s] on."""
        if self.config.mode == "realtime":
            commands, started = self.ages.fresh(commands, t)
            for command in started:
                logger.warning("robot %d: command for t = %.3f s is %.3f s old at t = %.3f s: "
                               "not applied", command.robot, command.t, t - command.t, t)
                self._event("stale_command", robot=command.robot, command_t=command.t,
                            age=t - command.t)
        for command in commands:
            self.world.set_command(command.robot, command.u, t)

    def _report_step(self) -> None:
        """Report the step :meth:`_advance` made last, once: tick k's missed deadlines
        (``tlfleet.sim.stats``), the robots the watchdog stopped at t_k and the contacts of the step
        to t_{k+1}, as events stamped with those times, in that order."""
        if self._unreported is None:
            return
        k, due, stopped = self._unreported
        self._unreported = None
        self.timing.close_tick(k, due)
        for robot in stopped:
            self.stats.watchdog_stops += 1
            logger.warning("watchdog: robot %d has had no command for %g s, stopped", robot,
                           self.world.watchdog)
            self._event_at(self.clock.time(k), "watchdog_stop", robot=robot,
                           last_command_t=self.world.robots[robot].last_command_t)
        for contact in self.world.drain_contacts():
            self.stats.contacts += 1
            data: dict[str, object] = {"a": contact.a, "b": contact.b}
            if contact.b == WALL:
                data["what"] = contact.what
            self._event_at(self.clock.time(k + 1), "contact", **data)

    def _finish(self) -> None:
        logger.info("sim time reached %g s", self.t)
        self.done = True

    # ----------------------------------------------------------------- inbox

    def _pump(self, timeout: float) -> None:
        """Handle everything the callbacks queued, waiting up to ``timeout`` [s] for the first."""
        cmds, inbox = self._cmds, self._inbox
        if cmds is not None:  # lockstep: commands on this thread, then what the callbacks queued
            item = cmds.recv(timeout if inbox.empty() else 0.0)
            while item is not None:
                self._on_command(item[0], item[1], self._now())
                item = cmds.recv(0.0)
            timeout = 0.0
        if timeout > 0.0 or not inbox.empty():  # (no raised Empty on every pump)
            try:
                item = inbox.get(timeout=timeout) if timeout > 0.0 else inbox.get_nowait()
            except queue.Empty:
                item = None
            while item is not None:
                kind, key, payload, arrival = item
                if kind == "cmd":
                    self._on_command(key, payload, arrival)
                elif kind == "checked":  # decoded and checked on arrival (the hardware bridge)
                    self._on_checked_command(payload, arrival)
                elif kind == "control":
                    self._on_control(key, payload)
                elif kind == "malformed":
                    self._malformed(key, payload)
                else:
                    self._on_alive(key, payload)
                try:
                    item = inbox.get_nowait()
                except queue.Empty:
                    item = None
        if self.malformed:
            self._report_malformed()

    def _on_command(self, key: str, payload: bytes, arrival: float) -> None:
        try:
            command = decode(Command, payload)
        except ProtocolError as exc:
            self._malformed(key, str(exc))
            return
        robot = self._cmd_robot.get(key)
        if (robot if robot is not None else keys.robot_of(key)) != command.robot:
            self._malformed(key, f"command of robot {command.robot} on another robot's key")
            return
        problem = self.bounds.command_problem(command)
        if problem is not None:
            self._malformed(key, f"implausible command: {problem}")
            return
        if command.robot in self.world.robots:
            try:
                self.world.check_command(command.robot, command.u)
            except ValueError as exc:
                self._malformed(key, str(exc))
                return
        self._on_checked_command(command, arrival)

    def _on_checked_command(self, command: Command, arrival: float) -> None:
        """A command that passed :meth:`_on_command`'s checks: to the collector, and its timing."""
        collector = self.lockstep if self.config.mode == "lockstep" else self.latest
        outcome = collector.offer(command)
        if outcome is Offer.ACCEPTED:
            # an answer to a spread frame is stamped with that frame's time, t_seq + s·dt
            offset = max(0, round((command.t - self.clock.time(command.seq)) / self._step))
            self.timing.command_arrived(command.robot, command.seq, arrival, offset=offset)
        elif outcome is Offer.EARLY and collector is self.latest:
            self.timing.answered(command.robot, command.seq)
        else:
            logger.debug("command of robot %d seq %d ignored: %s", command.robot, command.seq,
                         outcome.value)

    def _on_control(self, key: str, payload: bytes) -> None:
        try:
            control = decode(Control, payload)
        except ProtocolError as exc:
            self._malformed(key, str(exc))
            return
        if control.cmd == "start" and not self.started:
            logger.info("start")
            self.started = True
        elif control.cmd == "stop":
            logger.info("stop requested")
            self.stop_requested = True

    def _on_backfill(self, payload: bytes) -> bytes | None:
        """The ``sim/backfill`` queryable (on a zenoh thread): the ring's answer to a
        ``BackfillRequest``; a payload that does not decode gets no reply and is counted (by the
        loop, which owns the counters)."""
        try:
            request = decode(BackfillRequest, payload)
        except ProtocolError as exc:
            self._inbox.put(("malformed", self._keys["backfill"], str(exc), 0.0))
            return None
        return encode(self.ring.answer(request))

    def _on_alive(self, key: str, up: bool) -> None:
        parsed = keys.parse_alive(key)
        if parsed is None or parsed[0] != "agent" or not parsed[1].isdigit():
            return
        robot = int(parsed[1])
        if up:
            self.alive.add(robot)
        else:
            logger.info("agent of robot %d is gone", robot)
            self.alive.discard(robot)
            self.lockstep.drop(robot)

    # ----------------------------------------------------------------- output

    def _publish(self, key: str, message: object) -> None:
        self.transport.publish(key, encode(message))

    def _publish_frame(self, frame: MocapFrame, *,
                       schedules: bool = True) -> tuple[bytes, float]:
        """Encode ``frame`` once; publish it on ``mocap`` and (with ``schedules``) on
        ``mocap_every/d/φ`` for each control schedule (d ≥ 2, φ) of the fleet with
        ``seq % d == φ`` (keys.frame_keys) and on every ``mocap_at/s``. Returns the payload and
        the wall time [s] just before the first put."""
        payload = encode(frame)
        published = self._now()
        self.transport.publish(self._keys["mocap"], payload)
        if schedules:
            for divider, phase, key in self._every:
                if frame.seq % divider == phase:
                    self.transport.publish(key, payload)
            for key in self._at.values():
                self.transport.publish(key, payload)
        return payload, published

    def _publish_sub_frame(self, k: int, offset: int, frame_keys: tuple[str, ...]) -> None:
        """The frame of period k sampled ``offset`` physics steps after its tick (spread frames):
        t = t_k + offset·dt, seq k, so its answer is tick k's command. Only on ``frame_keys``:
        ``mocap`` and the recorder keep the tick frames."""
        frame = MocapFrame(self.clock.time(k) + offset * self._step, k,
                           self.world.mocap_poses(), ())
        payload = encode(frame)
        published = self._now()
        for key in frame_keys:
            self.transport.publish(key, payload)
        self.timing.frame_published(k, published, offset=offset)

    def _shared_tick(self, seq: int) -> bool:
        """A robot with control divider ≥ 2 is due at tick ``seq`` (tlfleet.sim.stats: shared ticks;
        ``due_robots``' rule, ``seq % d == phase``, over those robots only)."""
        return any(seq % divider == phase for divider, phase in self._slow_schedules)

    def _event(self, kind: str, **data: object) -> None:
        self._event_at(self.t, kind, **data)

    def _event_at(self, t: float, kind: str, **data: object) -> None:
        self._publish(self._keys["event"], Event(t, SOURCE, kind, dict(data)))

    def _malformed(self, key: str, reason: str) -> None:
        if key not in self._cmd_robot and key not in self._keys.values() and \
                key not in self.malformed and len(self.malformed) >= MAX_MALFORMED_KEYS:
            key = OTHER_KEYS  # a stranger's endless key names: counted, not one entry each
        self.malformed[key] += 1
        if self.malformed[key] == 1:  # later ones are logged as counts by _report_malformed
            logger.warning("malformed message on %s: %s", key, reason)

    def _report_malformed(self, force: bool = False) -> None:
        """Publish each key's malformed count when it grew, at most once per period per key."""
        now = self._now()
        for key, count in self.malformed.items():
            reported, when = self._reported.get(key, (0, -float("inf")))
            if count > reported and (force or now - when >= self.config.malformed_report_period):
                if reported:
                    logger.warning("%d malformed messages on %s so far", count, key)
                self._reported[key] = (count, now)
                self._event("malformed_message", key=key, count=count)

    def summary(self) -> dict[str, object]:
        """The run's counters: published as ``Event(kind="sim_stats")`` at the end.

        ``missed``/``due`` count control deadlines (``tlfleet.sim.stats``); ``latency_*_ms`` are
        frame publication → command arrival at the sim; ``ignored`` counts commands by reason.
        """
        s = self.stats
        counts = self.lockstep.counts + self.latest.counts
        return {
            "mode": self.config.mode, "ticks": s.ticks, "wall_time": s.wall_time,
            "deadline_misses": s.deadline_misses, "contacts": s.contacts,
            "watchdog_stops": s.watchdog_stops, "overruns": s.overruns,
            "ignored": {o.value: n for o, n in counts.items()
                        if o not in (Offer.ACCEPTED, Offer.EARLY)},
            "early": counts[Offer.EARLY],
            "malformed": sum(self.malformed.values()),
            "malformed_by_key": dict(self.malformed),
            "stale_commands": sum(self.ages.stale.values()),
            "backfill": self.ring.stats(),
            **self.timing.summary(),
        }

    def _log_summary(self, summary: dict[str, object]) -> None:
        s = self.stats
        rate = s.ticks / s.wall_time if s.wall_time > 0 else float("nan")
        logger.info("sim finished: %d ticks in %.2f s wall (%.0f ticks/s); %s", s.ticks,
                    s.wall_time, rate, summary)


def run_sim(transport: Transport, scenario: Scenario, config: SimConfig,
            stop: threading.Event | None = None) -> int:
    """Run the simulator on an open transport (the caller closes it)."""
    return SimProcess(transport, scenario, config, stop).run()


def main(config: SimProcessConfig) -> int:
    """``tlfleet sim``: load the scenario, open the transport, run, close the session."""
    scenario = load_scenario(config.scenario)
    sim_config = SimConfig.for_scenario(scenario, mode=config.mode, duration=config.duration,
                                        seed=config.seed, tick_timeout=config.tick_timeout,
                                        max_command_age=config.max_command_age,
                                        max_speed=config.max_speed,
                                        backfill_seconds=config.backfill_seconds)
    sys.setswitchinterval(SWITCH_INTERVAL)
    stop = threading.Event()
    install_signal_handlers(stop)
    transport = open_transport(config.transport)
    watch = None
    try:
        watch = CoordinatorWatch(transport, keys.alive(scenario.fleet, "coordinator", 0), stop,
                                 config.orphan_after, "sim")
        code = run_sim(transport, scenario, sim_config, stop)
        time.sleep(LINGER)  # let zenoh deliver the last frame and sim_done before closing
        return code
    finally:
        if watch is not None:
            watch.close()
        transport.close()
