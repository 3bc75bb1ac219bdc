"""Thread-safe hand-over between transport callbacks and an agent's loop (architecture.md §3).

Transport callbacks run on a transport thread (zenoh) or inside the sender's call (fake) and must
only store bytes and return (stack-notes.md §0, §1.7). Everything here is built for that:

* :class:`Mailbox`: the newest mocap frame (latest-value slot: older frames are simply
  overwritten, so a slow loop never works through a backlog of stale poses), pending control
  payloads, and a stop flag, behind one condition variable the loop waits on. The agent's
  callback validates a frame before storing it, so garbage never displaces a valid
  frame: the slot holds the newest *valid* frame, with its decoded message.
* :class:`CollabInbox`: decoded collaboration messages for the pure STL step, handed over with the
  deterministic one-step latency of the pure harness (``stl_harness``, latency 1).
* :class:`MalformedCounter`: counts undecodable or implausible payloads per key and per claimed
  source, logs them rate-limited and queues ``Event(kind="malformed_message")`` for the loop to
  publish; it never raises.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from tlfleet.bus.protocol.messages import Event

logger = logging.getLogger(__name__)


# A per-tick value, never changed once built; not frozen: a frozen __init__ costs 3-4x.
@dataclass(slots=True)
class Wakeup:
    """What :meth:`Mailbox.wait` hands the loop: a new frame payload (or None), the control
    payloads received since the last wake-up, and whether a stop was requested."""

    frame: bytes | None
    controls: tuple[bytes, ...]
    stopped: bool
    decoded: object = None  # the frame's MocapFrame when the callback already decoded it


class Mailbox:
    """Latest-frame slot + control queue + stop flag, guarded by one condition variable."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._frame: bytes | None = None
        self._decoded: object = None
        self._controls: list[bytes] = []
        self._stopped = False
        self.frames_received = 0  # every frame payload stored (for statistics)
        self.frames_overwritten = 0  # payloads replaced before the loop took them

    # callbacks (any thread): store and notify -------------------------------------------

    def put_frame(self, payload: bytes, decoded: object = None) -> None:
        with self._cond:
            if self._frame is not None:
                self.frames_overwritten += 1
            self._frame = payload
            self._decoded = decoded
            self.frames_received += 1
            self._cond.notify_all()

    def keep_frame(self, payload: bytes, decoded: object = None) -> None:
        """Store a frame the loop's own thread read itself (a channel): nobody waits
        for it, so neither the lock nor a notification; only that thread may call this, and it
        takes frames with :meth:`take`."""
        if self._frame is not None:
            self.frames_overwritten += 1
        self._frame = payload
        self._decoded = decoded
        self.frames_received += 1

    def put_control(self, payload: bytes) -> None:
        with self._cond:
            self._controls.append(payload)
            self._cond.notify_all()

    def stop(self) -> None:
        with self._cond:
            self._stopped = True
            self._cond.notify_all()

    @property
    def stopped(self) -> bool:
        with self._cond:
            return self._stopped

    # the loop ----------------------------------------------------------------------------

    def wait(self, timeout: float) -> Wakeup:
        """Block up to ``timeout`` [s] wall until a frame, a control payload or a stop is there;
        take and return what arrived (``frame`` None and no controls on a timeout)."""
        with self._cond:
            if self._frame is None and not self._controls and not self._stopped and timeout > 0:
                self._cond.wait(timeout)
            frame, self._frame = self._frame, None
            decoded, self._decoded = self._decoded, None
            controls, self._controls = tuple(self._controls), []
            return Wakeup(frame, controls, self._stopped, decoded)

    def take(self) -> Wakeup:
        """``wait(0.0)`` of a loop that stores its frames itself (:meth:`keep_frame`): the frame
        without the lock, which is taken only when a control or a stop is pending (an unlocked
        look: one arriving at this instant is taken at the next call; its callback wakes the
        loop's channel, so that call comes at once)."""
        frame, self._frame = self._frame, None
        decoded, self._decoded = self._decoded, None
        if self._controls or self._stopped:
            with self._cond:
                controls, self._controls = tuple(self._controls), []
                return Wakeup(frame, controls, self._stopped, decoded)
        return Wakeup(frame, (), False, decoded)

    def newer_frame(self, timeout: float) -> tuple[bytes, object] | None:
        """Wait up to ``timeout`` [s] for a frame only (no controls); take it, or None."""
        with self._cond:
            if self._frame is None and not self._stopped and timeout > 0:
                self._cond.wait(timeout)
            if self._frame is None:
                return None
            frame, self._frame = self._frame, None
            decoded, self._decoded = self._decoded, None
            return frame, decoded


@dataclass(frozen=True, slots=True)
class _Entry:
    t: float  # [s] the sender's sim time when it sent the message
    sender: int
    arrival: int
    message: object


class CollabInbox:
    """Collaboration messages waiting for the pure STL step.

    :meth:`take_before` hands over, in a fixed order, every message sent at a sim time earlier than
    the frame being processed. A message sent during tick k therefore reaches its receiver at tick
    k + 1 whatever the order in which the agents process tick k: the one-step latency of
    ``stl_harness.run_closed_loop(latency_steps=1)``, deterministic in lockstep. The order is
    (send time, sender id, arrival), which is the harness's order (agents step in ascending ids).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._entries: list[_Entry] = []
        self._arrivals = 0

    def put(self, t: float, sender: int, message: object) -> None:
        with self._lock:
            self._entries.append(_Entry(t, sender, self._arrivals, message))
            self._arrivals += 1

    def take_before(self, t: float) -> tuple[object, ...]:
        """Remove and return the messages sent before sim time ``t`` [s]."""
        with self._lock:
            ready = [e for e in self._entries if e.t < t]
            if not ready:
                return ()
            self._entries = [e for e in self._entries if not e.t < t]
        ready.sort(key=lambda e: (e.t, e.sender, e.arrival))
        return tuple(e.message for e in ready)

    def __len__(self) -> int:
        with self._lock:
            return len(self._entries)


class MalformedCounter:
    """Counts malformed payloads per key; logs and reports them at most every ``interval`` [s].

    ``record`` may be called from any thread; the loop publishes :meth:`take_events`. The first
    malformed payload on a key is always logged and reported; later ones are folded into the
    next report (``data["count"]`` is the running total on that key, ``data["new"]`` how many
    since the previous report). ``by_source`` counts per (key, claimed sender): the transport
    does not say who published a sample, so the sender is what the key or payload claims
    (``"?"`` when nothing does); ``kinds`` counts ``malformed`` (undecodable) apart from
    ``implausible`` (decoded, but out of the fleet's bounds or an implausible jump).
    """

    def __init__(self, source: str, interval: float = 1.0,
                 clock: Callable[[], float] = time.monotonic):
        self.source = source
        self.interval = interval
        self._clock = clock
        self._lock = threading.Lock()
        self.counts: dict[str, int] = {}
        self.by_source: dict[tuple[str, str], int] = {}
        self.kinds: dict[str, int] = {}
        self._reported: dict[str, tuple[float, int]] = {}  # key -> (wall time, count) of report
        self._events: list[Event] = []

    @property
    def total(self) -> int:
        with self._lock:
            return sum(self.counts.values())

    def record(self, key: str, error: object, t: float = 0.0, *, sender: str = "?",
               kind: str = "malformed") -> None:
        """One malformed payload on ``key`` (``error``: the decode error); ``t`` sim time [s]."""
        now = self._clock()
        with self._lock:
            count = self.counts.get(key, 0) + 1
            self.counts[key] = count
            self.by_source[(key, sender)] = self.by_source.get((key, sender), 0) + 1
            self.kinds[kind] = self.kinds.get(kind, 0) + 1
            last = self._reported.get(key)
            if last is not None and now - last[0] < self.interval:
                return
            new = count - (last[1] if last else 0)
            self._reported[key] = (now, count)
            self._events.append(Event(t=t, source=self.source, kind="malformed_message",
                                      data={"key": key, "count": count, "new": new,
                                            "sender": sender, "what": kind,
                                            "error": str(error)[:200]}))
        logger.warning("%s: malformed payload on %s (%d so far): %s", self.source, key, count,
                       error)

    def take_events(self) -> list[Event]:
        with self._lock:
            events, self._events = self._events, []
        return events
