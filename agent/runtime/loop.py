"""The one loop of an agent process: decode → pure ``step`` → encode/publish (style.md §3).

:class:`AgentLoop` is transport-agnostic (a :class:`~tlfleet.bus.transport.Transport`: zenoh in
processes, ``FakeNetwork`` in tests) and core-agnostic: the LTL and the STL agents are a
:class:`Core` each, whose ``step(state, TickInput) -> (state, TickOutput)`` holds all the logic.
The loop implements the time protocol of architecture.md §3:

* mission start: ``Control(start)``, or a frame that lists this robot in ``due`` (a lockstep sim
  only lists agents after the start, so a start message overtaken by the first frame costs
  nothing); nothing is sent before the start; ``Control(stop)`` ends the loop;
* a frame is *due* when it lists this robot in ``due`` (lockstep), or, when ``due`` is empty
  (realtime), when a new control period of ``divider`` mocap ticks, offset by ``phase``, has
  begun since the last frame computed (``(seq − phase) // divider`` changed:
  ``seq % divider == phase`` when no frame is skipped);
  the sim's preview frame (t = 0, seq = 0, due = ()) is never due, even after the start;
* per due frame: one ``step``; in lockstep the step's collaboration messages are sent by query
  (all in flight together) and their replies awaited **before**
  ``Command(robot, t=frame.t, seq=frame.seq, u)`` is published (so they are in their receivers'
  inboxes before the next frame: a deterministic one-step latency); in realtime the command goes
  first and the queries are only issued, so round trips delay neither this command nor the
  next frame; then status and events; then the core's optional
  ``after_command(state) -> state``: work the step deferred so as not to delay the command (the
  LTL executor's periodic global re-plan);
* frames: an agent whose robot has control divider d ≥ 2 and phase φ reads
  ``mocap_every/<d>/<φ>`` (the frames with ``seq % d == φ``, ``LoopConfig.decimated``) instead
  of every frame on ``mocap``: it can only be due at those ticks, lockstep or realtime; an
  every-tick robot at frame offset s ≥ 1 (``Scenario.frame_offset``) reads ``mocap_at/<s>``,
  where a realtime simulator publishes the frames it samples s physics steps after each tick;
* stale mocap: no frame for ``stale_after`` [s] wall after the start (a decimated loop adds twice
  the gap between its frames, ``LoopConfig.stale_limit``, or of the gap they lately came at
  when a lockstep fleet runs slower than real time, ``LoopConfig.stale_limit_at``; with
  ``LoopConfig.heartbeat`` it
  also calls mocap stale after ``stale_after`` without the sim's ``Clock``) → the
  zero command (with the
  last frame's t and seq) is published at once and every ``stale_after`` while it lasts, with one
  ``Event(stale_mocap)`` per episode; the next frame ends the episode;
* malformed payloads on mocap / control / collab are counted, logged rate-limited and reported as
  ``Event(malformed_message)``; they never end the loop;
* a mocap frame is decoded and checked in the transport callback, before it reaches
  the mailbox: undecodable, outside the fleet's bounds (``LoopConfig.bounds``) or an implausible
  sequence jump (``LoopConfig.max_jump``, :class:`tlfleet.bus.protocol.plausibility.FrameGate`) →
  counted and dropped, so garbage never displaces the newest valid frame; a frame older than the
  last one handled is ignored;
* resuming: in realtime, a due frame that comes more than ``stale_limit`` after the
  previous one (the process was frozen, or the link cut) first drains the backlog the transport
  delivers on resumption (``resume_settle``) and answers only the newest frame, reported as
  ``Event(resumed)``;
* events: the last ones are published again, marked ``replayed``, when the coordinator's
  liveliness token goes and returns (the link was down: :mod:`tlfleet.agent.runtime.event_log`).
"""

from __future__ import annotations

import logging
import statistics
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from tlfleet.agent.runtime.event_log import EventLog
from tlfleet.agent.runtime.inbox import Mailbox, MalformedCounter
from tlfleet.agent.runtime.peers import CollabLink
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.bounds import FleetBounds
from tlfleet.bus.protocol.codec import ProtocolError, decode, encode
from tlfleet.bus.protocol.fast_paths import command_bytes
from tlfleet.bus.protocol.messages import Clock, CollabMessage, Command, Control, Event, MocapFrame
from tlfleet.bus.protocol.plausibility import FrameGate, Verdict
from tlfleet.bus.transport import Channel, Closeable, Transport

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class LoopConfig:
    """Timing of one agent loop (times [s] wall unless stated)."""

    fleet: str
    robot: int
    divider: int = 1  # mocap ticks per control period: round(mocap_rate / control_rate)
    stale_after: float = 0.5  # no frame for this long → zero command
    # longest single block: a stop by signal (or a ``stop`` event) is noticed within it; the
    # loop blocks only until its next staleness check is due (``AgentLoop.block_for``), and a
    # Control(stop) or a frame wakes it at once
    wait_slice: float = 0.25
    bounds: FleetBounds | None = None  # plausibility of frames (None: codec checks only)
    max_jump: int | None = None  # [ticks] FrameGate of the mocap stream (None: no gate)
    resume_settle: float = 0.02  # after a freeze: wait this long for newer backlog frames
    # Subscribe to keys.mocap_every(fleet, divider, phase) instead of keys.mocap when divider ≥ 2:
    # only the frames this robot can be due for (seq % divider == phase). The staleness limit
    # then grows by the two gaps of divider − 1 unseen frames, (divider − 1) / mocap_rate [s] each.
    decimated: bool = False
    mocap_rate: float = 100.0  # [Hz] the sim's frame rate (used only when decimated)
    # A decimated loop also watches the sim's ``clock`` key (one tiny ``Clock`` every tick) and
    # calls mocap stale after ``stale_after`` without one, so it notices a lost simulator as
    # fast as a loop that reads every frame at the price of a callback per tick.
    heartbeat: bool = False
    # the tick of each control period at which the robot is due, in [0, divider)
    # (Scenario.control_phase: the LTL agents spread over the period)
    phase: int = 0
    # physics steps after its tick at which a realtime simulator samples this robot's frames
    # (Scenario.frame_offset); with ``decimated``, an every-tick robot at offset s ≥ 1 reads
    # keys.mocap_at(fleet, s) instead of keys.mocap
    offset: int = 0

    def __post_init__(self) -> None:
        if self.divider < 1:
            raise ValueError(f"LoopConfig.divider must be ≥ 1, got {self.divider}")
        if not 0 <= self.phase < self.divider:
            raise ValueError(f"LoopConfig.phase must be in [0, {self.divider}), got {self.phase}")
        if self.offset < 0:
            raise ValueError(f"LoopConfig.offset must be ≥ 0, got {self.offset}")
        if self.stale_after <= 0:
            raise ValueError(f"LoopConfig.stale_after must be positive, got {self.stale_after}")
        if not self.mocap_rate > 0:
            raise ValueError(f"LoopConfig.mocap_rate must be positive, got {self.mocap_rate}")

    @property
    def frames_decimated(self) -> bool:
        """True when the loop reads only every ``divider``-th frame (``mocap_every``)."""
        return self.decimated and self.divider > 1

    @property
    def stale_limit(self) -> float:
        """[s] wall without a frame after which mocap is stale: ``stale_after``, plus twice the
        expected gap (divider − 1) / mocap_rate between the frames of a decimated loop."""
        if not self.frames_decimated:
            return self.stale_after
        return self.stale_after + 2.0 * (self.divider - 1) / self.mocap_rate

    def stale_limit_at(self, frame_gap: float) -> float:
        """``stale_limit`` for a decimated loop whose frames have lately come ``frame_gap`` [s]
        wall apart: a lockstep fleet slower than real time spaces them beyond the nominal
        ``divider / mocap_rate``, which is the fleet's pace, not stale mocap."""
        if not self.frames_decimated:
            return self.stale_after
        return max(self.stale_limit,
                   self.stale_after + 2.0 * (frame_gap - 1.0 / self.mocap_rate))

    @property
    def watches_clock(self) -> bool:
        """True when the loop watches ``clock`` for staleness (a decimated loop with
        ``heartbeat``; a loop that reads every frame needs no heartbeat)."""
        return self.heartbeat and self.frames_decimated


# A per-tick value, never changed once built; not frozen: a frozen __init__ costs 3-4x.
@dataclass(slots=True)
class TickInput:
    """One due frame, the collaboration messages delivered for it (core messages) and the peers
    the runtime currently cannot reach."""

    frame: MocapFrame
    inbox: tuple[Any, ...] = ()
    unreachable: frozenset[int] = frozenset()


# A per-tick value, never changed once built; not frozen: a frozen __init__ costs 3-4x.
@dataclass(slots=True)
class TickOutput:
    """The command ``u`` (unicycle (v [m/s], ω [rad/s]); omni world-frame (vx, vy [m/s],
    ω [rad/s])), an optional status, events, and collaboration messages to send first."""

    u: tuple[float, ...]
    status: Any = None  # LtlStatus | StlStatus | None
    events: tuple[Event, ...] = ()
    messages: tuple[CollabMessage, ...] = ()


class Core(Protocol):
    """A pure agent: all decisions of a tick in ``step``."""

    robot: int
    zero: tuple[float, ...]  # the stop command

    def step(self, state: Any, inputs: TickInput) -> tuple[Any, TickOutput]: ...

    # optional: ``after_command(state) -> state``, run once the step's command is published


@dataclass
class LoopStats:
    """Counters for tests, logs and benchmarks."""

    frames: int = 0
    steps: int = 0
    commands: int = 0
    stale_episodes: int = 0
    stale_commands: int = 0
    step_time: float = 0.0  # [s] wall, total time inside core.step
    max_step_time: float = 0.0  # [s] wall
    collab_failures: int = 0
    collab_time: float = 0.0  # [s] wall, total time the loop spent sending (lockstep: + replies)
    max_collab_time: float = 0.0  # [s] wall
    resumes: int = 0  # frames that came after a freeze / partition
    backlog_dropped: int = 0  # frames of the backlog skipped on resumption
    old_frames: int = 0  # frames older than the last one handled, ignored
    after_time: float = 0.0  # [s] wall, total time inside core.after_command


class AgentLoop:
    """Drive one :class:`Core` from a transport (see the module docstring for the protocol).

    ``open()`` subscribes (and serves the collab queryable when ``link`` is given), ``ready()``
    declares the liveliness token ``alive/agent/<robot>``, ``run(stop)`` loops until
    ``Control(stop)`` or ``stop`` is set, ``close()`` undeclares everything. Tests may instead
    call ``run_once(timeout)`` to process whatever arrived, deterministically.
    """

    def __init__(self, transport: Transport, config: LoopConfig, core: Core, state: Any, *,
                 link: CollabLink | None = None, malformed: MalformedCounter | None = None,
                 clock: Callable[[], float] = time.monotonic):
        self.transport = transport
        self.config = config
        self.core = core
        self.state = state
        self.link = link
        self.source = f"agent/{config.robot}"
        self.malformed = malformed or MalformedCounter(self.source, clock=clock)
        self.clock = clock
        self.mailbox = Mailbox()
        self.stats = LoopStats()
        self.events = EventLog(transport, config.fleet, self.source)
        self._after_command = getattr(core, "after_command", None)
        self.started = False
        self.stopped = False
        self._handles: list[Closeable] = []
        self._last_frame_wall: float | None = None
        self._last_clock_wall: float | None = None  # [s] wall of the last Clock (heartbeat)
        self._last_frame: MocapFrame | None = None
        self._last_period: int | None = None
        self._last_seq: int | None = None
        self._stale = False
        self._stale_sent = -float("inf")
        self.gate = FrameGate(config.max_jump) if config.max_jump else None
        self._channel: Channel | None = None
        fleet, robot = config.fleet, config.robot
        mocap = (keys.robot_frames(fleet, config.divider, config.phase, config.offset)
                 if config.decimated else keys.mocap(fleet))
        self._stale_limit = config.stale_limit
        self._gaps: deque[float] = deque(maxlen=8)  # [s] wall per frame period, lately
        self._keys = {"mocap": mocap, "control": keys.control(fleet),
                      "cmd": keys.cmd(fleet, robot), "status": keys.status(fleet, robot),
                      "alive": keys.alive(fleet, "agent", robot),
                      "clock": keys.clock(fleet)}

    # set-up and tear-down -------------------------------------------------------------------

    def open(self) -> None:
        """Subscribe. Frames come through a channel read by the loop's own thread when the
        transport has ``subscribe_channel`` (zenoh, the fake bus: no thread hand-over
        per frame), else through a callback into the mailbox."""
        box = self.mailbox
        subscribe_channel = getattr(self.transport, "subscribe_channel", None)
        if subscribe_channel is not None:
            channel = subscribe_channel(self._keys["mocap"])
            self._channel = channel
            self._handles.append(channel)

            def on_control(_key: str, payload: bytes) -> None:
                box.put_control(payload)
                channel.wake()
        else:
            self._handles.append(self.transport.subscribe(self._keys["mocap"],
                                                          self._receive_frame))

            def on_control(_key: str, payload: bytes) -> None:
                box.put_control(payload)
        self._handles.append(self.transport.subscribe(self._keys["control"], on_control))
        if self.config.watches_clock:
            self._handles.append(self.transport.subscribe(self._keys["clock"], self._on_clock))
        self._handles.append(self.events.watch())
        if self.link is not None:
            self.link.open()

    def ready(self) -> None:
        """Declare ``alive/agent/<robot>``: from now on this agent answers due frames."""
        self._handles.append(self.transport.declare_alive(self._keys["alive"]))

    def close(self) -> None:
        self.mailbox.stop()
        if self._channel is not None:
            self._channel.wake()
        if self.link is not None:
            self.link.close()
        for handle in reversed(self._handles):
            try:
                handle.close()
            except Exception:  # a dying session must not prevent the others from closing
                logger.exception("%s: closing a transport handle failed", self.source)
        self._handles.clear()

    def summary(self) -> dict[str, object]:
        """Counters of this loop for ``Event(kind="agent_stats")`` and logs (times in ms)."""
        st = self.stats
        out: dict[str, object] = {
            "frames": st.frames, "steps": st.steps, "commands": st.commands,
            "mean_step_ms": 1e3 * st.step_time / st.steps if st.steps else 0.0,
            "mean_after_command_ms": 1e3 * st.after_time / st.steps if st.steps else 0.0,
            "max_step_ms": 1e3 * st.max_step_time, "stale_episodes": st.stale_episodes,
            "stale_commands": st.stale_commands, "frames_overwritten":
            self.mailbox.frames_overwritten, "malformed": self.malformed.total,
            "malformed_by_kind": dict(self.malformed.kinds), "resumes": st.resumes,
            "backlog_dropped": st.backlog_dropped, "old_frames": st.old_frames,
            "events_replayed": self.events.replayed}
        if self.link is not None:
            out.update(collab_sent=self.link.sent, collab_failed=self.link.failed,
                       collab_received=self.link.received, collab_refused=self.link.refused,
                       mean_collab_ms=1e3 * st.collab_time / max(self.link.sent, 1),
                       max_collab_ms=1e3 * st.max_collab_time)
        return out

    def publish_startup_event(self, event: Event) -> None:
        """Publish an event made before the start; it is published again at the start
        (:meth:`tlfleet.agent.runtime.event_log.EventLog.replay_startup`)."""
        self.events.publish_startup(event)

    def publish_event(self, event: Event) -> None:
        """Publish ``event``; it is published again if the coordinator's token goes and comes
        back soon after (:mod:`tlfleet.agent.runtime.event_log`)."""
        self.events.publish(event)

    # the loop --------------------------------------------------------------------------------

    def run(self, stop: threading.Event | None = None) -> int:
        """Loop until ``Control(stop)`` or ``stop``; returns the exit code (0)."""
        while not (stop is not None and stop.is_set()):
            if not self.run_once(self.block_for()):
                break
        return 0

    def block_for(self) -> float:
        """[s] how long the next wait may block: until the staleness check of ``_check_stale``
        is next due (the frame limit, the heartbeat's silence limit, or the next zero command
        while stale; at least 1 ms), at most ``wait_slice``. Frames arrive far more often, so a
        steady loop is woken by them, and a zenoh channel's timer only at these deadlines
        (4 instead of 20 timer wake-ups a second)."""
        config = self.config
        if not self.started or self._last_frame_wall is None:
            return config.wait_slice
        if self._stale:
            due = self._stale_sent + config.stale_after
        else:
            due = self._last_frame_wall + self._stale_limit
            if config.watches_clock:
                heard = self._last_frame_wall
                if self._last_clock_wall is not None:
                    heard = max(heard, self._last_clock_wall)
                due = min(due, heard + config.stale_after)
        return min(config.wait_slice, max(due - self.clock(), 0.001))

    def run_once(self, timeout: float = 0.0) -> bool:
        """Wait up to ``timeout`` [s] for input and handle it; False once stopped."""
        if self._channel is not None:  # frames read here, kept in the mailbox without its lock
            self._pump_channel(timeout)
            wake = self.mailbox.take()
        else:
            wake = self.mailbox.wait(timeout)
        for payload in wake.controls:
            self._on_control(payload)
        if wake.stopped:
            self.stopped = True
        if self.stopped:
            return False
        if wake.frame is not None:
            self._on_frame(wake.frame, wake.decoded)
        else:
            self._check_stale()
        self._flush_malformed()
        return True

    def _pump_channel(self, timeout: float) -> None:
        """Read the frame channel on this thread: wait up to ``timeout`` [s] for the first
        sample (a wake-up or the timeout returns None), then take whatever else is queued;
        each frame is checked as the callback would (``_receive_frame``) and the newest valid
        one waits in the mailbox's slot (``Mailbox.keep_frame``: this thread's own hand-over)."""
        channel = self._channel
        item = channel.recv(timeout)
        while item is not None:
            self._receive_frame(item[0], item[1])
            item = channel.recv(0.0)

    def _newer_frame(self, timeout: float) -> tuple[bytes, object] | None:
        if self._channel is not None:
            self._pump_channel(timeout)
            timeout = 0.0
        return self.mailbox.newer_frame(timeout)

    @property
    def last_t(self) -> float:
        """Sim time [s] of the last frame handled (0 before any)."""
        return self._last_frame.t if self._last_frame is not None else 0.0

    def _on_control(self, payload: bytes) -> None:
        try:
            control = decode(Control, payload)
        except ProtocolError as exc:
            self.malformed.record(self._keys["control"], exc, self.last_t)
            return
        if control.cmd == "start":
            if not self.started:
                logger.info("%s: start (t0 = %g)", self.source, control.t0)
                self._start()
        else:
            logger.info("%s: stop", self.source)
            self.stopped = True

    def _start(self) -> None:
        self.started = True
        self._last_frame_wall = self.clock()  # staleness counts from the start
        self.events.replay_startup()

    def _receive_frame(self, key: str, payload: bytes) -> None:
        """Transport callback: store the frame only when it is valid and plausible."""
        try:
            frame = decode(MocapFrame, payload)
        except ProtocolError as exc:
            self.malformed.record(key, exc, self.last_t, sender="sim")
            return
        bounds = self.config.bounds
        problem = bounds.frame_problem(frame) if bounds is not None else None
        if problem is None and self.gate is not None:
            verdict = self.gate.offer(frame.seq)
            if verdict is Verdict.HELD:
                problem = (f"seq {frame.seq} jumps from {self.gate.last} (more than "
                           f"{self.gate.max_jump} ticks): held until confirmed")
        if problem is not None:
            self.malformed.record(key, f"MocapFrame: implausible: {problem}", self.last_t,
                                  sender="sim", kind="implausible")
            return
        if self._channel is not None:  # called by _pump_channel on the loop's own thread
            self.mailbox.keep_frame(payload, frame)
        else:
            self.mailbox.put_frame(payload, frame)

    def _on_clock(self, key: str, payload: bytes) -> None:
        """Transport callback (heartbeat): note when the sim was last heard from. A malformed
        ``Clock`` is counted and does not count as a heartbeat; the frame limit
        (``stale_limit``) still applies whatever the clock key carries."""
        try:
            decode(Clock, payload)
        except ProtocolError as exc:
            self.malformed.record(key, exc, self.last_t, sender="sim")
            return
        self._last_clock_wall = self.clock()

    def _on_frame(self, payload: bytes, decoded: object = None) -> None:
        if isinstance(decoded, MocapFrame):
            frame = decoded
        else:
            try:
                frame = decode(MocapFrame, payload)
            except ProtocolError as exc:
                self.malformed.record(self._keys["mocap"], exc, self.last_t)
                self._check_stale()
                return
        last = self._last_frame
        if last is not None and frame.seq < last.seq:
            self.stats.old_frames += 1  # reordered or late: the newer one was handled
            return
        if (not frame.due and self.started and self._last_frame_wall is not None
                and self.clock() - self._last_frame_wall > self._stale_limit
                and frame.seq > 0):
            frame = self._resume(frame)
        robot = self.config.robot
        listed = robot in frame.due
        if listed and not self.started:
            self._start()
        if not self.started:
            return
        self.stats.frames += 1
        now = self.clock()
        if (self.config.frames_decimated and last is not None and not self._stale
                and self._last_frame_wall is not None and frame.seq > last.seq):
            periods = (frame.seq - last.seq) / self.config.divider
            self._gaps.append((now - self._last_frame_wall) / max(periods, 1.0))
            self._stale_limit = self.config.stale_limit_at(statistics.median(self._gaps))
        self._last_frame = frame
        self._last_frame_wall = now
        if self._stale:
            self._stale = False
            logger.info("%s: mocap frames are back (t = %.3f)", self.source, frame.t)
        if frame.due:
            due = listed and frame.seq != self._last_seq
        elif frame.seq == 0 and frame.t == 0.0:
            # The sim's preview frame, which may still arrive after Control(start): answering it
            # would make a lockstep agent skip the real tick 0 (same seq) and miss its deadline.
            # In realtime mode tick 0 looks the same and goes unanswered too: 1 period only.
            due = False
        else:
            due = self._period(frame.seq) != self._last_period
        if not due:
            return
        if frame.pose(robot) is None:
            self.malformed.record(self._keys["mocap"],
                                  ProtocolError(f"MocapFrame.poses: no row for robot {robot}"),
                                  frame.t)
            return
        self._last_seq = frame.seq
        self._last_period = self._period(frame.seq)
        self._tick(frame)

    def _period(self, seq: int) -> int:
        """The control period frame ``seq`` belongs to (it begins at a tick with
        ``seq % divider == phase``)."""
        return (seq - self.config.phase) // self.config.divider

    def _resume(self, frame: MocapFrame) -> MocapFrame:
        """The first frame after a freeze or a partition (realtime): drop the backlog the
        transport is still delivering and return the newest frame."""
        gap = self.clock() - (self._last_frame_wall or self.clock())
        dropped = 0
        newest = frame
        deadline = time.monotonic() + 10 * self.config.resume_settle
        while time.monotonic() < deadline:
            got = self._newer_frame(self.config.resume_settle)
            if got is None:
                break
            payload, decoded = got
            candidate = decoded if isinstance(decoded, MocapFrame) else None
            if candidate is None:
                try:
                    candidate = decode(MocapFrame, payload)
                except ProtocolError:
                    continue
            if candidate.seq >= newest.seq:
                dropped += 1
                newest = candidate
        self.stats.resumes += 1
        self.stats.backlog_dropped += dropped
        logger.warning("%s: resumed after %.2f s without frames; %d backlog frame(s) dropped, "
                       "answering t = %.3f", self.source, gap, dropped, newest.t)
        self.publish_event(Event(newest.t, self.source, "resumed",
                                 {"gap": gap, "dropped": dropped, "from_t": frame.t,
                                  "to_t": newest.t}))
        return newest

    def _tick(self, frame: MocapFrame) -> None:
        link = self.link
        inputs = TickInput(frame,
                           link.inbox.take_before(frame.t) if link is not None else (),
                           link.unreachable if link is not None else frozenset())
        began = time.perf_counter()
        self.state, out = self.core.step(self.state, inputs)
        spent = time.perf_counter() - began
        self.stats.steps += 1
        self.stats.step_time += spent
        self.stats.max_step_time = max(self.stats.max_step_time, spent)
        if out.messages and link is None:
            raise TypeError(f"{self.source}: the core sent collaboration messages but the loop "
                            "has no CollabLink")
        lockstep = bool(frame.due)
        if lockstep:  # every message in its receiver's inbox before the sim's next frame
            self._send(out.messages, wait=True)
        self._publish_command(frame, out.u)
        if not lockstep:  # realtime: neither the command nor the next frame waits for replies
            self._send(out.messages, wait=False)
        if out.status is not None:
            self.transport.publish(self._keys["status"], encode(out.status))
        for event in out.events:
            self.publish_event(event)
        if self._after_command is not None:
            began = time.perf_counter()
            self.state = self._after_command(self.state)
            self.stats.after_time += time.perf_counter() - began

    def _send(self, messages: tuple[CollabMessage, ...], *, wait: bool) -> None:
        if not messages:
            return
        began = time.perf_counter()
        self.stats.collab_failures += self.link.send_all(messages, wait=wait)
        spent = time.perf_counter() - began
        self.stats.collab_time += spent
        self.stats.max_collab_time = max(self.stats.max_collab_time, spent)

    def _publish_command(self, frame: MocapFrame, u: tuple[float, ...]) -> None:
        robot, t, seq = self.config.robot, frame.t, frame.seq
        payload = command_bytes(robot, t, seq, u)  # written in C from the fields when it can
        if payload is None:
            payload = encode(Command(robot, t, seq, tuple(map(float, u))))
        self.transport.publish(self._keys["cmd"], payload)
        self.stats.commands += 1

    def _check_stale(self) -> None:
        if not self.started or self._last_frame_wall is None:
            return
        now = self.clock()
        heard = self._last_frame_wall  # [s] wall: the last we heard from the simulator
        if self.config.watches_clock and self._last_clock_wall is not None:
            heard = max(heard, self._last_clock_wall)
        silent = (self.config.watches_clock and now - heard >= self.config.stale_after)
        if now - self._last_frame_wall < self._stale_limit and not silent:
            return
        if not self._stale:
            self._stale = True
            self._stale_sent = -float("inf")
            self.stats.stale_episodes += 1
            silence = now - self._last_frame_wall
            logger.warning("%s: no mocap frame for %.2f s (nothing from the simulator for "
                           "%.2f s): zero command", self.source, silence, now - heard)
            self.publish_event(Event(self.last_t, self.source, "stale_mocap",
                                     {"silence": silence, "sim_silence": now - heard,
                                      "last_seq": self._last_frame.seq
                                      if self._last_frame is not None else -1}))
        if now - self._stale_sent >= self.config.stale_after:
            self._stale_sent = now
            frame = self._last_frame or MocapFrame(0.0, -1, ())
            self._publish_command(frame, self.core.zero)
            self.stats.stale_commands += 1

    def _flush_malformed(self) -> None:
        for event in self.malformed.take_events():
            self.publish_event(event)
