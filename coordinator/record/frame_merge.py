"""The recorder's frames merged by sequence number across gaps (the backfill).

In realtime, a link cut longer than the zenoh lease loses every frame the simulator publishes
until the link is back (fault-injection notes §5.3); the first frame after it reveals the gap:
its ``seq`` jumps. :class:`FrameMerger` then holds the frames after the gap back (in memory,
by seq) and asks for the missing ones (:meth:`FrameMerger.requests`: seq ranges for a
``BackfillRequest`` on ``sim/backfill``, every ``retry`` s), until each missing seq has
arrived — from a ``BackfillReply`` (:meth:`FrameMerger.backfill`) or late on the live stream —
or is *gone*: a reply covered it without a frame (the simulator's ring no longer holds it), the
gap waited ``wait`` s, more than ``max_held`` frames are held, or the run ends
(:meth:`FrameMerger.finish`). Frames are handed to ``write`` in strictly increasing seq, each
once: duplicates (overlapping replies, a frame both late and backfilled) and frames older than
what was written are dropped and counted. A gone seq is skipped and named: the ``backfill``
event of its gap lists it, and :meth:`FrameMerger.summary` goes to ``run.json``.

Without a gap nothing is held but the newest frame (the recorder's hold-back: the simulator's
last pre-start frame and tick 0 both carry seq 0, and the later one wins), so a run without
faults writes the same rows as before. While a gap waits, at most ``wait`` s of rows are in
memory only (the recorder flushes every second otherwise).

Events (``record(kind, t, data)``, t = sim time [s]): ``trajectory_gap`` when a gap is seen
(its seqs and the times of the frames around it), ``backfill`` when the written rows have passed
it (frames backfilled, arrived late, unrecovered with their seq ranges and times, queries, the
wall time it waited).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from tlfleet.bus.protocol.messages import MocapFrame

MAX_REQUEST_FRAMES = 2048  # seqs one BackfillRequest asks for at most (the reply's frame budget)


@dataclass
class Gap:
    """The seqs ``first``..``last`` the live stream skipped."""

    first: int
    last: int
    opened: float  # [s] wall (the merger's clock) when the gap was seen
    t_before: float  # [s] sim time of the frame before the gap
    t_after: float  # [s] sim time of the frame that revealed it
    missing: set[int]  # still to come
    gone: set[int] = field(default_factory=set)  # a reply covered them without a frame
    backfilled: int = 0
    late: int = 0  # arrived on the live stream after all
    skipped: list[int] = field(default_factory=list)  # seqs passed without a frame
    queries: int = 0
    next_query: float = 0.0  # [s] wall
    given_up: bool = False
    oldest_held: int | None = None  # the simulator's oldest ring seq, from its last reply

    @property
    def frames(self) -> int:
        return self.last - self.first + 1

    def t_of(self, seq: int) -> float:
        """Sim time of ``seq`` [s], between the frames around the gap (t = seq / mocap rate, so
        the interpolation is exact)."""
        step = (self.t_after - self.t_before) / (self.frames + 1)
        return self.t_before + (seq - self.first + 1) * step


def seq_ranges(seqs: list[int]) -> list[tuple[int, int]]:
    """Ascending ``seqs`` as inclusive runs: ``[1, 2, 3, 7]`` → ``[(1, 3), (7, 7)]``."""
    out: list[tuple[int, int]] = []
    for seq in seqs:
        if out and seq == out[-1][1] + 1:
            out[-1] = (out[-1][0], seq)
        else:
            out.append((seq, seq))
    return out


class FrameMerger:
    """Frames in, frames out in strictly increasing seq with gaps backfilled (module docstring).

    ``write(frame)`` receives each frame once, in seq order; ``record(kind, t, data)`` the
    events; ``clock`` is the wall clock [s] of ``wait`` and ``retry``.
    """

    def __init__(self, write: Callable[[MocapFrame], None],
                 record: Callable[[str, float, dict[str, Any]], None],
                 clock: Callable[[], float], *, wait: float = 3.0, retry: float = 0.25,
                 max_held: int = 8192):
        if not (wait > 0.0 and retry > 0.0 and max_held >= 1):
            raise ValueError(f"FrameMerger: wait = {wait!r} s and retry = {retry!r} s must be "
                             f"> 0, max_held = {max_held!r} ≥ 1")
        self._write = write
        self._record = record
        self._clock = clock
        self.wait = wait  # [s] wall a gap waits for its frames at most
        self.retry = retry  # [s] wall between two requests for one gap
        self.max_held = max_held
        self.held: dict[int, MocapFrame] = {}
        self.gaps: list[Gap] = []  # open, ascending
        self.closed_gaps: list[Gap] = []
        self.cursor: int | None = None  # the next seq to write (None before the first frame)
        self.newest = -1
        self.stale = 0  # frames at or below what was already written (or passed)
        self.duplicates = 0  # backfilled frames that were no longer missing
        self.ignored = 0  # backfilled frames outside the range their reply covers
        self._finishing = False

    # ----------------------------------------------------------------- input

    def offer(self, frame: MocapFrame) -> None:
        """A frame of the live stream."""
        seq = frame.seq
        held = self.held
        if self.cursor is None:  # the first frame anchors the stream
            self.cursor = self.newest = seq
            held[seq] = frame
            return
        if seq == self.newest + 1 and not self.gaps:  # the usual case: the next frame
            pending = held.pop(self.newest, None)
            if pending is not None:
                self._emit(pending)
            self.newest = seq
            held[seq] = frame
            return
        if seq < self.cursor:
            self.stale += 1
            return
        if seq > self.newest:
            if seq > self.newest + 1:
                self._open(self.newest + 1, seq - 1, frame.t)
            self.newest = seq
            held[seq] = frame
        elif seq in held:
            held[seq] = frame  # the same seq again before it was written: the later one wins
        else:
            gap = self._gap_of(seq)
            if gap is None:
                self.stale += 1
                return
            gap.missing.discard(seq)
            gap.gone.discard(seq)
            gap.late += 1
            held[seq] = frame
        self._release()

    def backfill(self, first: int, last: int, oldest: int, frames: list[MocapFrame]) -> None:
        """A ``BackfillReply`` covering seqs ``first``..``last`` with (decoded, checked)
        ``frames``; a covered seq still missing afterwards is gone (``oldest``: the ring's
        oldest seq, kept for the report)."""
        for frame in frames:
            seq = frame.seq
            if not first <= seq <= last:
                self.ignored += 1
                continue
            gap = self._gap_of(seq)
            if gap is None or seq in self.held:
                self.duplicates += 1
                continue
            gap.missing.discard(seq)
            gap.gone.discard(seq)
            gap.backfilled += 1
            self.held[seq] = frame
        for gap in self.gaps:
            if gap.first <= last and first <= gap.last:
                gap.oldest_held = oldest
                covered = {s for s in gap.missing if first <= s <= last}
                gap.missing -= covered
                gap.gone |= covered
        self._release()

    def requests(self, force: bool = False) -> list[tuple[int, int]]:
        """The seq ranges to ask for now (each gap's lowest missing seqs, at most
        :data:`MAX_REQUEST_FRAMES`); ``force``: whether or not a request is due."""
        if not self.gaps:
            return []
        now = self._clock()
        out = []
        for gap in self.gaps:
            if gap.given_up or not gap.missing or not (force or now >= gap.next_query):
                continue
            lo = min(gap.missing)
            out.append((lo, min(max(gap.missing), lo + MAX_REQUEST_FRAMES - 1)))
            gap.queries += 1
            gap.next_query = now + self.retry
        return out

    def poll(self) -> None:
        """Give up gaps that waited ``wait`` s, and the oldest while more than ``max_held``
        frames are held; write what can be written."""
        now = self._clock()
        for gap in self.gaps:
            if now - gap.opened >= self.wait:
                gap.given_up = True
        while len(self.held) > self.max_held:  # (_release closes gaps: no loop over the list)
            gap = next((g for g in self.gaps if not g.given_up), None)
            if gap is None:
                break
            gap.given_up = True
            self._release()
        self._release()

    def finish(self) -> None:
        """The run is over: give up every gap and write every frame held (the newest too)."""
        self._finishing = True
        for gap in self.gaps:
            gap.given_up = True
        self._release()

    # ----------------------------------------------------------------- state

    @property
    def waiting(self) -> bool:
        """Some gap still waits for frames."""
        return any(not gap.given_up and gap.missing for gap in self.gaps)

    def summary(self) -> dict[str, Any]:
        """For ``run.json``: gaps, frames missed / backfilled / late / unrecovered (with their
        seq ranges and sim times), queries, dropped duplicates."""
        gaps = self.closed_gaps + self.gaps
        unrecovered = [{"first": a, "last": b, "frames": b - a + 1, "t_first": g.t_of(a),
                        "t_last": g.t_of(b), "oldest_held": g.oldest_held}
                       for g in gaps for a, b in seq_ranges(g.skipped)]
        return {"gaps": len(gaps), "missed": sum(g.frames for g in gaps),
                "backfilled": sum(g.backfilled for g in gaps),
                "late": sum(g.late for g in gaps),
                "unrecovered": sum(len(g.skipped) for g in gaps),
                "unrecovered_ranges": unrecovered, "queries": sum(g.queries for g in gaps),
                "duplicates": self.duplicates, "ignored": self.ignored, "stale": self.stale}

    # ----------------------------------------------------------------- internals

    def _open(self, first: int, last: int, t_after: float) -> None:
        before = self.held.get(first - 1)
        t_before = before.t if before is not None else max(
            (f.t for s, f in self.held.items() if s < first), default=t_after)
        gap = Gap(first, last, self._clock(), t_before, t_after, set(range(first, last + 1)))
        self.gaps.append(gap)
        self._record("trajectory_gap", t_after, {
            "first": first, "last": last, "frames": gap.frames, "t_before": t_before,
            "t_after": t_after})

    def _gap_of(self, seq: int) -> Gap | None:
        """The open gap still missing ``seq`` (or that gave it up as gone)."""
        for gap in self.gaps:
            if gap.first <= seq <= gap.last and (seq in gap.missing or seq in gap.gone):
                return gap
        return None

    def _emit(self, frame: MocapFrame) -> None:
        self._write(frame)
        self.cursor = frame.seq + 1

    def _release(self) -> None:
        held, gaps = self.held, self.gaps
        while self.cursor is not None:
            seq = self.cursor
            frame = held.get(seq)
            if frame is not None:
                if seq == self.newest and not self._finishing:
                    break  # the newest frame is held back
                del held[seq]
                self._emit(frame)
            elif seq > self.newest or not gaps:
                break
            else:
                gap = gaps[0]  # every seq in [cursor, newest] is held or in a gap
                if seq < gap.first:  # (cannot happen: nothing else is below the lowest gap)
                    self.cursor = gap.first
                    continue
                if seq in gap.missing and not gap.given_up:
                    break  # waiting for it
                gap.missing.discard(seq)
                gap.gone.discard(seq)
                gap.skipped.append(seq)
                self.cursor = seq + 1
            while gaps and self.cursor > gaps[0].last:
                self._close(gaps.pop(0))

    def _close(self, gap: Gap) -> None:
        self.closed_gaps.append(gap)
        self._record("backfill", gap.t_after, {
            "first": gap.first, "last": gap.last, "frames": gap.frames,
            "backfilled": gap.backfilled, "late": gap.late, "unrecovered": len(gap.skipped),
            "unrecovered_ranges": [[a, b] for a, b in seq_ranges(gap.skipped)],
            "queries": gap.queries, "waited": self._clock() - gap.opened,
            "oldest_held": gap.oldest_held})
