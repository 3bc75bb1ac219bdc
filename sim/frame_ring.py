"""The simulator's ring of recent frames, for the recorder's backfill.

When a link is cut for longer than the zenoh lease, the session drops and every frame the
simulator publishes until it is back never reaches the coordinator's recorder (fault-injection
notes §5.3: "once the lease expires, samples published while the transport is down are lost").
The simulator keeps its last frames here, exactly as published (the encoded ``MocapFrame``
payload, so keeping one costs a deque append and no encoding), and answers the recorder's
``BackfillRequest`` on ``sim/backfill`` with the ones it missed (``tlfleet.bus.protocol.messages``).

The ring is bounded twice: at most ``max_frames`` frames and ``max_bytes`` bytes of payload
(the oldest go first; the newest frame is always kept). :func:`ring_size` turns the simulator's
``backfill_seconds`` (default :data:`BACKFILL_SECONDS`) into the frame bound. A frame older than
the ring's span is gone for good: a reply covers it without a frame, and the recorder names it
as an unrecoverable gap (``tlfleet.coordinator.record.recorder``).

Thread-safe: the simulator's loop appends, a zenoh thread answers queries; one lock, held for
an append or for a copy of the ring's references.
"""

from __future__ import annotations

import bisect
import math
import threading
from collections import deque

from tlfleet.bus.protocol.bounds import BACKFILL_REPLY_BYTES, BACKFILL_REPLY_FRAMES
from tlfleet.bus.protocol.messages import BackfillReply, BackfillRequest

#: [s] sim time of frames the simulator keeps by default: the fault tests cut the simulator's
#: link for 2 s and lose ≈ 2.5 s of frames (the cut, then zenoh's reconnect); 10 s covers a cut of
#: ≈ 7 s plus zenoh's reconnect back-off (≤ 4 s when the link was down, notes §5.3) with margin
BACKFILL_SECONDS = 10.0
BACKFILL_BYTES = 8 * 1024 * 1024  # payload bytes held at most (≈ 44 000 frames of 5 robots)


def ring_size(seconds: float, mocap_rate: float) -> int:
    """Frames in ``seconds`` [s] of sim time at ``mocap_rate`` [Hz] (at least 1)."""
    if not (seconds >= 0.0 and math.isfinite(seconds)):
        raise ValueError(f"backfill_seconds = {seconds!r}: must be a finite number ≥ 0")
    return max(1, math.ceil(seconds * mocap_rate))


class FrameRing:
    """The last published frames, ``(seq, payload)`` with strictly increasing ``seq``."""

    def __init__(self, max_frames: int, max_bytes: int = BACKFILL_BYTES):
        if max_frames < 1 or max_bytes < 1:
            raise ValueError(f"FrameRing bounds must be ≥ 1: max_frames = {max_frames}, "
                             f"max_bytes = {max_bytes}")
        self.max_frames = max_frames
        self.max_bytes = max_bytes
        self._lock = threading.Lock()
        self._seqs: deque[int] = deque()
        self._payloads: deque[bytes] = deque()
        self.bytes = 0  # payload bytes held
        self.appended = 0
        self.evicted = 0
        self.queries = 0  # requests answered
        self.frames_sent = 0

    def __len__(self) -> int:
        return len(self._seqs)

    @property
    def oldest(self) -> int:
        """The oldest seq held (−1 when empty)."""
        seqs = self._seqs
        return seqs[0] if seqs else -1

    def append(self, seq: int, payload: bytes) -> None:
        """Keep the frame ``seq`` (greater than every seq held), evicting the oldest frames
        beyond the bounds (never the one just added)."""
        with self._lock:
            seqs, payloads = self._seqs, self._payloads
            if seqs and seq <= seqs[-1]:
                raise ValueError(f"FrameRing.append: seq {seq} does not follow {seqs[-1]}")
            seqs.append(seq)
            payloads.append(payload)
            self.bytes += len(payload)
            self.appended += 1
            while len(seqs) > 1 and (len(seqs) > self.max_frames or self.bytes > self.max_bytes):
                seqs.popleft()
                self.bytes -= len(payloads.popleft())
                self.evicted += 1

    def answer(self, request: BackfillRequest, max_bytes: int = BACKFILL_REPLY_BYTES,
               max_frames: int = BACKFILL_REPLY_FRAMES) -> BackfillReply:
        """The reply to ``request``: the held frames of ``first``..``last``, in seq order, up to
        ``max_bytes`` of payload and ``max_frames`` frames (at least one frame when there is
        one); the reply covers up to the last frame it carries, or the whole request when every
        held frame of it fits."""
        with self._lock:
            seqs, payloads = list(self._seqs), list(self._payloads)
            self.queries += 1
        first, last = request.first, request.last
        start = bisect.bisect_left(seqs, first)
        stop = bisect.bisect_right(seqs, last)
        frames: list[bytes] = []
        size = 0
        covered = last
        for i in range(start, stop):
            payload = payloads[i]
            if frames and (len(frames) >= max_frames or size + len(payload) > max_bytes):
                covered = seqs[i] - 1  # the rest in the next request
                break
            frames.append(payload)
            size += len(payload)
        with self._lock:
            self.frames_sent += len(frames)
        return BackfillReply(first=first, last=covered, oldest=seqs[0] if seqs else -1,
                             frames=tuple(frames))

    def stats(self) -> dict[str, int]:
        """Counters for ``sim_stats``: the bounds, what is held and what was evicted or sent."""
        return {"max_frames": self.max_frames, "max_bytes": self.max_bytes,
                "frames": len(self._seqs), "bytes": self.bytes, "evicted": self.evicted,
                "queries": self.queries, "frames_sent": self.frames_sent}
