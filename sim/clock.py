"""Sim time and wall-clock pacing (architecture.md §3).

The simulator owns time: tick k happens at sim time t_k = k / mocap_rate [s] (computed from k, so
it never accumulates rounding error), with t = 0 at ``Control(start)``. In realtime mode the tick
loop is paced on a monotonic wall clock by :class:`Pacer`; in lockstep mode no pacing happens.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class TickClock:
    """Tick ↔ sim-time conversion at ``mocap_rate`` [Hz]."""

    mocap_rate: float

    @property
    def period(self) -> float:
        """[s] sim time between two ticks (one mocap frame)."""
        return 1.0 / self.mocap_rate

    def time(self, tick: int) -> float:
        """t_k = k / mocap_rate [s]."""
        return tick / self.mocap_rate

    def last_tick(self, duration: float) -> int:
        """The tick at which sim time reaches ``duration`` [s] (the run's final frame)."""
        return max(0, math.ceil(duration * self.mocap_rate - 1e-9))


class Pacer:
    """Keeps a loop on a wall-clock period: tick k is due at wall time T_0 + k·period.

    The loop asks :meth:`remaining` (and waits on its own inbox meanwhile), then calls
    :meth:`advance` once per tick. If it falls more than one period behind (an overrun), the
    schedule restarts from now instead of bursting to catch up, and the overrun is counted.
    ``now`` is injectable for tests (default ``time.monotonic``).
    """

    def __init__(self, period: float, now: Callable[[], float] = time.monotonic):
        self.period = period  # [s] wall
        self._now = now
        self.next_due = now() + period
        self.overruns = 0

    def remaining(self) -> float:
        """[s] wall time left until the next tick is due (≤ 0: due now)."""
        return self.next_due - self._now()

    def advance(self) -> None:
        """Mark the due tick as done and schedule the next one."""
        now = self._now()
        self.next_due += self.period
        if now - self.next_due > self.period:
            self.overruns += 1
            self.next_due = now + self.period
