"""An agent's recent events, published again when the coordinator comes back into reach.

Why: an event published while the agent's link to the router is down is lost — zenoh has no
session to send it on, or sends it on a transport the router has already closed. The typical
case is a frozen agent (``docker pause``, ``SIGSTOP``) whose lease expired meanwhile: on
resumption it answers the newest frame and publishes ``Event(resumed)`` within a few hundred
milliseconds, before its zenoh runtime has noticed that the router dropped it and reconnected.
The coordinator then never records that the agent resumed.

What: :class:`EventLog` keeps the last :data:`CAPACITY` events an agent published with their wall
time, and watches the coordinator's liveliness token (``alive/coordinator/0``). When that token
goes (the agent's link is down, or the coordinator is gone) and comes back, the events published
from ``window`` seconds before the loss onwards are published again, each with
``data["replayed"] = True``. The window reaches back before the loss was *noticed* because the
events in question are published in the moments between a resumption and the notice.

Delivery is therefore at least once; the coordinator's recorder drops a replayed event it has
already recorded (:mod:`tlfleet.coordinator.record.replay_dedup`) and records the others with their
mark, so
``events.jsonl`` says which ones came late. Events older than the window, or pushed out of the
ring, are not replayed: the bound is :data:`CAPACITY` events and ``window`` seconds.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import replace

from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import encode
from tlfleet.bus.protocol.events import role_of_source
from tlfleet.bus.protocol.messages import EVENT_REPLAYED, Event
from tlfleet.bus.transport import Closeable, Transport

logger = logging.getLogger(__name__)

CAPACITY = 64  # events kept for a replay
WINDOW = 5.0  # [s] wall: events published this long before the loss are replayed too


class EventLog:
    """Publishes an agent's events on its ``event/agent/<id>`` and replays the recent ones after the
    coordinator's token returns (module docstring). Thread-safe: events are published from the
    loop's thread, the replay runs on the transport's liveliness callback thread."""

    def __init__(self, transport: Transport, fleet: str, source: str, *,
                 window: float = WINDOW, capacity: int = CAPACITY,
                 clock: Callable[[], float] = time.monotonic):
        if not window >= 0.0:
            raise ValueError(f"EventLog window = {window!r} s: must be ≥ 0")
        if capacity < 1:
            raise ValueError(f"EventLog capacity = {capacity!r}: must be ≥ 1")
        self.transport = transport
        self.source = source
        self.window = window
        self._clock = clock
        role = role_of_source(source)
        if role is None:
            raise ValueError(f"EventLog source {source!r} names no process (sim, agent/<id>)")
        self._key = keys.event(fleet, *role)
        self._coordinator = keys.alive(fleet, "coordinator", 0)
        self._recent: deque[tuple[float, Event]] = deque(maxlen=capacity)
        self._lock = threading.Lock()
        self._lost_at: float | None = None  # [s] wall when the coordinator's token went
        self.replays = 0  # times the log was published again
        self.replayed = 0  # events published again, in all
        self._startup: list[Event] = []  # published before the start, again at the start

    def watch(self) -> Closeable:
        """Watch the coordinator's token; the caller closes the handle."""
        return self.transport.watch_alive(self._coordinator, self._on_coordinator)

    def publish(self, event: Event) -> None:
        """Publish ``event`` and keep it for a replay."""
        with self._lock:
            self._recent.append((self._clock(), event))
        self.transport.publish(self._key, encode(event))

    def publish_startup(self, event: Event) -> None:
        """Publish a start-up event (``plan_ready``, ``coupling_limits``: made before the start)
        and keep it for :meth:`replay_startup`."""
        self._startup.append(event)
        self.publish(event)

    def replay_startup(self) -> int:
        """At the mission start: publish the start-up events again, marked replayed.

        Why: they are published as soon as the liveliness token is up, when the agent's session
        may not yet know the route to the coordinator's subscriber (a zenoh sample with no known
        subscriber is dropped: 2 of 13 first ``plan_ready`` were recorded). ``Control(start)``
        has come from the coordinator, whose subscriber was declared before it, so the route is
        known now; the recorder drops the copy of one it already has
        (:mod:`tlfleet.coordinator.record.replay_dedup`). Returns how many were published."""
        again, self._startup = self._startup, []
        for event in again:
            self.transport.publish(self._key, encode(
                replace(event, data={**event.data, EVENT_REPLAYED: True})))
        self.replayed += len(again)
        return len(again)

    def _on_coordinator(self, _key: str, alive: bool) -> None:
        if not alive:
            with self._lock:
                if self._lost_at is None:
                    self._lost_at = self._clock()
            return
        with self._lock:
            lost_at, self._lost_at = self._lost_at, None
            if lost_at is None:  # its first declaration, or a duplicate: nothing was lost
                return
            since = lost_at - self.window
            again = [event for wall, event in self._recent if wall >= since]
        for event in again:
            self.transport.publish(self._key, encode(
                replace(event, data={**event.data, EVENT_REPLAYED: True})))
        self.replays += 1
        self.replayed += len(again)
        if again:
            logger.info("%s: the coordinator is back in reach; published %d recent event(s) "
                        "again", self.source, len(again))
