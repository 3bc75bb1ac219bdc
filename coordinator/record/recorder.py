"""Records a run as it goes into the run directory (``tlfleet.coordinator.record.rundir`` holds the
layout, the formats, the writers and the readers).

Everything is appended and flushed at least every ``flush_period`` (1 s), so a crash loses at most
the last second. :class:`Recorder` is a plain consumer of decoded messages (no transport);
:class:`RecorderTap` wires it to a transport with callbacks that only queue bytes
(stack-notes.md §0) and decodes in the coordinator's loop.

Backfill: frames reach ``trajectory.csv`` through a
:class:`~tlfleet.coordinator.record.frame_merge.FrameMerger`, so a gap in the live stream (a link
cut longer than the zenoh lease) is held open while :class:`RecorderTap` asks the simulator for the
missing frames (``BackfillRequest`` on ``sim/backfill``); they are merged by seq, and what cannot be
recovered is named in ``events.jsonl`` (``trajectory_gap``, ``backfill``) and ``run.json``
(``backfill``, :meth:`Recorder.backfill_summary`).
"""

from __future__ import annotations

import json
import logging
import math
import queue
import shutil
import time
from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO, Any

from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.bounds import FleetBounds
from tlfleet.bus.protocol.codec import ProtocolError, decode, encode, peek_kind
from tlfleet.bus.protocol.events import data_problem
from tlfleet.bus.protocol.messages import (
    BackfillReply,
    BackfillRequest,
    Event,
    LtlStatus,
    MocapFrame,
    StlStatus,
)
from tlfleet.bus.protocol.plausibility import FrameGate, Verdict
from tlfleet.bus.transport import Channel, Closeable, Transport
from tlfleet.coordinator.record import rundir
from tlfleet.coordinator.record.frame_merge import FrameMerger
from tlfleet.coordinator.record.replay_dedup import EventDedup
from tlfleet.coordinator.record.rundir import AFTER_SIM_DONE
from tlfleet.coordinator.record.trust import RecordCheck

logger = logging.getLogger(__name__)

COORDINATOR_SOURCE = "coordinator"  # Event.source of the events the coordinator makes


class Recorder:
    """Writes ``trajectory.csv``, ``status.csv`` and ``events.jsonl`` of one run.

    ``robot_ids`` fixes the trajectory columns (ascending). Frames are written only after
    :meth:`start` (the mission start), with strictly increasing ``seq``; the newest frame is held
    back until a newer one arrives (the sim's last pre-start frame and tick 0 both carry seq 0,
    the later one wins), then written — so the file's times increase strictly. After a jump in
    ``seq`` the frames wait (at most ``backfill_wait`` s of wall time) for the missing ones: from
    :meth:`on_backfill` or late on the live stream (:mod:`tlfleet.coordinator.record.frame_merge`).
    """

    def __init__(self, run_dir: Path, robot_ids: Sequence[int], *,
                 flush_period: float = 1.0, clock: Callable[[], float] = time.monotonic,
                 backfill_wait: float = 3.0):
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.robot_ids = tuple(sorted(robot_ids))
        self.flush_period = flush_period  # [s] wall
        self._clock = clock
        self._last_flush = clock()
        self._started = False
        self._merger = FrameMerger(self._write_frame, self._record, clock, wait=backfill_wait)
        self.frames_written = 0
        self.frames_invalid = 0
        self.last_t = 0.0  # [s] sim time of the newest frame seen after start
        self.statuses = 0
        self.events = 0
        self.event_kinds: Counter[str] = Counter()
        self.sim_done_t: float | None = None  # [s] the sim time the newest sim_done claims
        self._traj_writer = rundir.TrajectoryWriter(self.run_dir / rundir.TRAJECTORY,
                                                    self.robot_ids)
        self._status_writer = rundir.StatusWriter(self.run_dir / rundir.STATUS)
        self._traj: IO[str] = self._traj_writer.handle
        self._status: IO[str] = self._status_writer.handle
        self._events: IO[str] = open(self.run_dir / rundir.EVENTS, "w",  # noqa: SIM115
                                     encoding="utf-8")
        self.flush()

    # ----------------------------------------------------------------- files beside the stream

    def copy_scenario(self, source: Path) -> None:
        shutil.copyfile(source, self.run_dir / rundir.SCENARIO)

    def write_run_info(self, info: dict[str, Any]) -> None:
        """(Re)write ``run.json`` with ``info`` (small, rewritten whole)."""
        path = self.run_dir / rundir.RUN_INFO
        path.write_text(json.dumps(info, indent=2, default=rundir.json_default) + "\n",
                        encoding="utf-8")

    # ----------------------------------------------------------------- stream

    def start(self) -> None:
        """Mission start: frames from now on are trajectory rows."""
        self._started = True

    def on_mocap(self, frame: MocapFrame) -> None:
        if not self._started:
            return
        self._merger.offer(frame)
        self.last_t = max(self.last_t, frame.t)
        self._maybe_flush()

    def on_backfill(self, first: int, last: int, oldest: int,
                    frames: list[MocapFrame]) -> None:
        """A ``BackfillReply`` covering seqs ``first``..``last`` (its frames decoded and checked
        by the tap; ``oldest``: the simulator ring's oldest seq)."""
        if self._started and not self._traj.closed:
            self._merger.backfill(first, last, oldest, frames)
            self._maybe_flush()

    def backfill_requests(self, force: bool = False) -> list[tuple[int, int]]:
        """Seq ranges to ask the simulator for now (``force``: even if none is due)."""
        return self._merger.requests(force) if not self._traj.closed else []

    @property
    def backfill_waiting(self) -> bool:
        return self._merger.waiting

    def poll(self) -> None:
        """Give up gaps that waited too long and write what can be written (the tap calls
        this every drain)."""
        if not self._traj.closed:
            self._merger.poll()

    def backfill_summary(self) -> dict[str, Any]:
        """The gaps of the live stream and what the backfill recovered (for ``run.json``)."""
        return self._merger.summary()

    def _record(self, kind: str, t: float, data: dict[str, Any]) -> None:
        if kind == "backfill" and data["unrecovered"]:
            logger.warning("trajectory.csv misses %d frames of the gap seq %d–%d (runs %s): "
                           "not recovered", data["unrecovered"], data["first"], data["last"],
                           data["unrecovered_ranges"])
        self.on_event(Event(t=t, source=COORDINATOR_SOURCE, kind=kind, data=data))

    @property
    def frames_skipped(self) -> int:
        """Frames not written: a robot missing or a value not finite, or a frame of that seq
        (or a later one) already written."""
        return self.frames_invalid + self._merger.stale

    def _write_frame(self, frame: MocapFrame) -> None:
        poses = {int(row[0]): row[1:4] for row in frame.poses}
        try:
            values = [float(v) for r in self.robot_ids for v in poses[r]]
        except KeyError as exc:
            logger.warning("mocap frame seq %d lacks robot %s: not recorded", frame.seq, exc)
            self.frames_invalid += 1
            return
        if not all(math.isfinite(v) for v in values) or not math.isfinite(frame.t):
            logger.warning("mocap frame seq %d has a non-finite value: not recorded", frame.seq)
            self.frames_invalid += 1
            return
        self._traj_writer.write(frame.t, values)
        self.frames_written += 1

    def on_status(self, status: LtlStatus | StlStatus) -> None:
        self._status_writer.write(status)
        self.statuses += 1
        self._maybe_flush()

    def on_event(self, event: Event) -> None:
        self._events.write(rundir.event_line(event))
        self.events += 1
        self.event_kinds[event.kind] += 1
        if event.kind == "sim_done":
            self.sim_done_t = event.t
        if event.kind in ("process_died", "sim_done"):
            self._events.flush()  # rare and important: on disk at once
        self._maybe_flush()

    # ----------------------------------------------------------------- files

    def _maybe_flush(self) -> None:
        if self._clock() - self._last_flush >= self.flush_period:
            self.flush()

    def flush(self) -> None:
        for handle in (self._traj, self._status, self._events):
            handle.flush()
        self._last_flush = self._clock()

    def close(self) -> None:
        """Write the held-back frames (a gap still open is given up and named) and close every
        file (idempotent)."""
        if self._traj.closed:
            return
        self._merger.finish()
        for handle in (self._traj, self._status, self._events):
            handle.close()


class RecorderTap:
    """Subscribes a :class:`Recorder` to a fleet's mocap, status and event keys.

    The samples wait in one channel per key (``Transport.subscribe_channel``: no
    Python thread is woken per sample, 100+ times a second) or, on a transport without
    channels, are queued by callbacks; :meth:`drain` (called from the coordinator's loop)
    decodes and records. Undecodable payloads are counted per key kind in ``malformed`` and
    per (kind, claimed source) in ``malformed_by_source``, logged at most once a second per kind,
    never raised. With ``bounds``/``max_jump``, implausible frames (outside the run,
    the arena, or a sequence jump not confirmed by the next frame: ``FrameGate``) count as
    malformed and are not recorded, so a spoofed frame neither ends the run (t = 10⁹) nor makes the
    recorder drop real rows (a high seq). An event whose data has the wrong types for its kind
    (:func:`tlfleet.bus.protocol.events.data_problem`) is malformed. With ``robot_ids``, events
    on a key that is not their claimed source's, and statuses whose claimed identity does not
    hold, are recorded as ``flagged_event`` instead (:mod:`tlfleet.coordinator.record.trust`);
    with ``record_check`` also the simulator's claims that contradict the frames recorded.

    Backfill: each :meth:`drain` sends the recorder's due ``BackfillRequest`` s to the
    simulator's ``sim/backfill`` queryable (``query_async``: the replies are queued by the
    transport's thread and recorded by a later drain). Every frame of a reply is decoded and
    checked (``bounds``) like a live one, but not by the gate: it is an old frame asked for. A
    reply or frame that fails counts as malformed (kind ``backfill``). :meth:`close` makes one
    last, blocking attempt (at most :attr:`FINAL_BACKFILL_TIMEOUT`) for a gap still open.
    """

    LOG_PERIOD = 1.0  # [s] wall between two log lines of one kind
    #: samples each of the tap's channels holds (zenoh: a full one holds up the coordinator's
    #: link): the coordinator drains every 50 ms; this is minutes of a 100 Hz fleet's frames
    CHANNEL_CAPACITY = 1 << 16
    BACKFILL_TIMEOUT = 0.5  # [s] wall a backfill query waits for its reply
    FINAL_BACKFILL_TIMEOUT = 1.0  # [s] wall of the last attempt, when the tap closes

    def __init__(self, transport: Transport, fleet: str, recorder: Recorder,
                 on_message: Callable[[str, Any], None] | None = None, *,
                 bounds: FleetBounds | None = None, max_jump: int | None = None,
                 robot_ids: Sequence[int] | None = None,
                 record_check: RecordCheck | None = None):
        self.recorder = recorder
        self.fleet = fleet
        self.transport = transport
        self._backfill_key = keys.sim_backfill(fleet)
        self.backfill_queries = 0
        self.bounds = bounds
        self.gate = FrameGate(max_jump) if max_jump else None
        self.robot_ids = frozenset(robot_ids) if robot_ids is not None else None
        self.record_check = record_check
        self.flagged = 0
        self.dedup = EventDedup()  # replayed agent events (tlfleet.agent.runtime.event_log)
        #: the simulator's ``sim_done`` was recorded: every later event is marked
        #: ``AFTER_SIM_DONE`` (said once the mission ended; it never changes the verdict)
        self.sim_done = False
        self.malformed_by_source: Counter[tuple[str, str]] = Counter()
        self._logged: dict[str, float] = {}
        self.malformed: Counter[str] = Counter()
        self.latest_frame: MocapFrame | None = None
        self._on_message = on_message
        self._queue: queue.SimpleQueue[tuple[str, str, bytes]] = queue.SimpleQueue()
        self._handles: list[Closeable] = []
        self._channels: list[tuple[str, Channel]] = []
        subscribe_channel = getattr(transport, "subscribe_channel", None)
        for what, key in (("mocap", keys.mocap(fleet)), ("status", keys.all_statuses(fleet)),
                          ("event", keys.all_events(fleet))):
            if subscribe_channel is not None:
                channel = subscribe_channel(key, capacity=self.CHANNEL_CAPACITY)
                self._channels.append((what, channel))
                self._handles.append(channel)
            else:
                self._handles.append(transport.subscribe(key, self._enqueue(what)))

    def _enqueue(self, what: str) -> Callable[[str, bytes], None]:
        put = self._queue.put

        def callback(key: str, payload: bytes) -> None:
            put((what, key, payload))

        return callback

    def drain(self, limit: int | None = None) -> int:
        """Decode and record what has arrived (at most ``limit`` samples); returns the count.

        With channels, frames first, then statuses, then events (each kind in its arrival
        order; the sim publishes its last frame before ``sim_done``)."""
        n = 0
        for what, channel in self._channels:
            while limit is None or n < limit:
                item = channel.recv(0.0)
                if item is None:
                    break
                n += 1
                self._handle(what, item[0], item[1])
        self._ask_backfill()
        while limit is None or n < limit:
            try:
                what, key, payload = self._queue.get_nowait()
            except queue.Empty:
                break
            n += 1
            self._handle(what, key, payload)
        self.recorder.poll()
        return n

    def _ask_backfill(self, force: bool = False) -> None:
        """Send the recorder's due backfill requests; the replies come back on the queue."""
        put, key = self._queue.put, self._backfill_key

        def on_done(replies: list[bytes]) -> None:
            for reply in replies:
                put(("backfill", key, reply))

        for first, last in self.recorder.backfill_requests(force):
            self.backfill_queries += 1
            try:
                self.transport.query_async(key, encode(BackfillRequest(first, last)),
                                           self.BACKFILL_TIMEOUT, on_done)
            except Exception:  # a closing session: the gap is given up and named later
                logger.warning("backfill query for seqs %d–%d failed", first, last,
                               exc_info=True)

    def _handle(self, what: str, key: str, payload: bytes) -> None:
        try:
            if what == "backfill":
                self._on_backfill(payload)
                return
            if what == "mocap":
                frame = decode(MocapFrame, payload)
                self._check_frame(frame)
                if self.record_check is not None:
                    self.record_check.on_frame(frame)
                self.latest_frame = frame
                self.recorder.on_mocap(frame)
                message: Any = frame
            elif what == "status":
                cls = StlStatus if peek_kind(payload) == "StlStatus" else LtlStatus
                message = decode(cls, payload)
                if self.robot_ids is not None:
                    from tlfleet.coordinator.record.trust import status_problem

                    problem = status_problem(keys.robot_of(key), message)
                    if problem is None and message.robot not in self.robot_ids:
                        problem = f"status of robot {message.robot}, not in this fleet"
                    if problem:
                        raise ProtocolError(f"{type(message).__name__}: implausible: {problem}")
                self.recorder.on_status(message)
            else:
                message = decode(Event, payload)
                parsed = keys.parse_event(key)
                if parsed is not None and parsed[0] == COORDINATOR_SOURCE:
                    return  # ours are recorded when made
                problem = data_problem(message.kind, message.data)
                if problem is not None:
                    raise ProtocolError(f"Event: {problem}")
                if self._flag(message, key) or not self.dedup.admit(message):
                    return
                if self.sim_done:
                    message = Event(message.t, message.source, message.kind,
                                    {**message.data, AFTER_SIM_DONE: True})
                self.recorder.on_event(message)
                if message.kind == "sim_done" and message.source == "sim":
                    self.sim_done = self._sim_done_genuine()
        except ProtocolError as exc:
            self._count(what, key, payload, exc)
            return
        if self._on_message is not None:
            self._on_message(what, message)

    def _on_backfill(self, payload: bytes) -> None:
        reply = decode(BackfillReply, payload)
        frames = []
        for data in reply.frames:
            try:
                frame = decode(MocapFrame, data)
                self._check_frame(frame, gated=False)  # an old frame asked for: no seq gate
            except ProtocolError as exc:
                self._count("backfill", self._backfill_key, data, exc)
                continue
            frames.append(frame)
        self.recorder.on_backfill(reply.first, reply.last, reply.oldest, frames)

    def _check_frame(self, frame: MocapFrame, gated: bool = True) -> None:
        """ProtocolError for a frame out of the fleet's bounds or (``gated``: a live frame) whose
        seq jump the gate holds until confirmed."""
        problem = self.bounds.frame_problem(frame) if self.bounds is not None else None
        if problem is None and gated and self.gate is not None and \
                self.gate.offer(frame.seq) is Verdict.HELD:
            problem = f"seq {frame.seq} jumps from {self.gate.last}: held until confirmed"
        if problem is not None:
            raise ProtocolError(f"MocapFrame: implausible: {problem}")

    def _sim_done_genuine(self) -> bool:
        """A ``sim_done`` ends the mission for the marks only when the frames have reached the
        end of the run (:func:`tlfleet.coordinator.record.trust.sim_done_plausible`): a forged
        one mid-run must not hide what follows from the verdict."""
        if self.bounds is None:
            return True
        from tlfleet.coordinator.record.trust import sim_done_plausible

        last_t = self.latest_frame.t if self.latest_frame is not None else 0.0
        return sim_done_plausible(last_t, self.bounds.duration, sim_ended=False)

    def _flag(self, event: Event, key: str) -> bool:
        """Record an event whose claimed identity does not hold, or whose claim contradicts the
        record, as ``flagged_event`` (:mod:`tlfleet.coordinator.record.trust`)."""
        if self.robot_ids is None:
            return False
        from tlfleet.coordinator.record.trust import FLAGGED, event_problem

        problem = event_problem(event, key, self.robot_ids)
        if problem is None and event.source == "sim" and self.record_check is not None:
            problem = self.record_check.contradiction(event)
        if problem is None:
            return False
        self.flagged += 1
        if self._may_log("flagged"):
            logger.warning("flagged event %r from %r: %s (%d so far)", event.kind[:40],
                           event.source[:40], problem, self.flagged)
        self.recorder.on_event(Event(
            t=event.t, source=COORDINATOR_SOURCE, kind=FLAGGED,
            data={"key": key[-80:], "claimed_source": event.source[:80],
                  "claimed_kind": event.kind[:80], "reason": problem}))
        return True

    def _count(self, what: str, key: str, payload: bytes, exc: Exception) -> None:
        if what == "status":
            source = f"agent/{keys.robot_of(key)}"
        elif what == "event":
            parsed = keys.parse_event(key)
            source = "/".join(parsed)[:40] if parsed is not None else "?"
        else:
            source = "sim"
        self.malformed[what] += 1
        self.malformed_by_source[(what, source)] += 1
        if self._may_log(what):
            logger.warning("malformed payload on %s (%d of this kind so far): %s", key,
                           self.malformed[what], exc)

    def _final_backfill(self) -> None:
        """The run ends with a gap still open: one blocking attempt for its frames."""
        for first, last in self.recorder.backfill_requests(force=True):
            self.backfill_queries += 1
            try:
                replies = self.transport.query(self._backfill_key,
                                               encode(BackfillRequest(first, last)),
                                               self.FINAL_BACKFILL_TIMEOUT)
            except Exception:
                logger.warning("final backfill query failed", exc_info=True)
                return
            for reply in replies:
                self._handle("backfill", self._backfill_key, reply)
        self.drain()

    def _may_log(self, what: str) -> bool:
        now = time.monotonic()
        if now - self._logged.get(what, -float("inf")) < self.LOG_PERIOD:
            return False
        self._logged[what] = now
        return True

    def close(self) -> None:
        # what the channels still hold is not recorded: the coordinator drains before closing
        if self.recorder.backfill_waiting:
            self._final_backfill()
        self._channels.clear()
        for handle in self._handles:
            handle.close()
        self._handles.clear()
