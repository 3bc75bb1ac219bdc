"""Which mocap frames a receiver trusts when the sequence number jumps.

The simulator's frames move forward one tick at a time; a receiver may skip some (its mailbox
keeps only the newest) but never sees ``seq`` go backwards or leap far ahead unless something is
wrong: a spoofed frame, a replayed one, a restarted simulator. :class:`FrameGate` accepts a frame
whose ``seq`` lies in ``[last, last + max_jump]`` of the last accepted one. Any other frame is a
*candidate*: rejected now, and accepted (re-anchoring the gate) only when the next frame confirms
it — lies in ``(candidate, candidate + max_jump]``. So one spoofed frame (``seq`` = 10⁹, or the
final tick while the run is at 2 s) never displaces the real stream, while a real jump — the
receiver was frozen (SIGSTOP) or cut off for longer than ``max_jump`` ticks — costs one frame.

``max_jump`` [ticks] is chosen by the receiver: one second of mocap frames, and at least two
control periods of the slowest robot (a lockstep LTL agent legitimately sees every 20th frame).
Thread-safe: transport callbacks call :meth:`FrameGate.offer`.
"""

from __future__ import annotations

import enum
import threading


class Verdict(enum.Enum):
    ACCEPTED = "accepted"
    CONFIRMED = "confirmed"  # accepted: it confirms the jump of the previous candidate
    HELD = "held"  # rejected for now: a jump that the next frame must confirm


class FrameGate:
    """Plausibility of a stream of sequence numbers (see the module docstring)."""

    def __init__(self, max_jump: int):
        if max_jump < 1:
            raise ValueError(f"FrameGate.max_jump must be ≥ 1, got {max_jump}")
        self.max_jump = max_jump
        self._lock = threading.Lock()
        self.last: int | None = None
        self.candidate: int | None = None
        self.held = 0  # frames rejected as implausible jumps
        self.confirmed = 0  # jumps accepted after confirmation

    def offer(self, seq: int) -> Verdict:
        with self._lock:
            last = self.last
            if (last is None and seq <= self.max_jump) or (
                    last is not None and last <= seq <= last + self.max_jump):
                self.last = seq
                self.candidate = None
                return Verdict.ACCEPTED
            cand = self.candidate
            if cand is not None and cand < seq <= cand + self.max_jump:
                self.last = seq
                self.candidate = None
                self.confirmed += 1
                return Verdict.CONFIRMED
            self.candidate = seq
            self.held += 1
            return Verdict.HELD


def max_jump_ticks(mocap_rate: float, dividers: list[int] | tuple[int, ...]) -> int:
    """The gate's ``max_jump`` for a fleet: 1 s of frames, ≥ 2 periods of the slowest robot + 2."""
    return max(round(mocap_rate), 2 * max(dividers, default=1) + 2)
