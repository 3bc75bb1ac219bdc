"""An in-memory bus for tests: synchronous, deterministic delivery between fake transports.

:class:`FakeTransport` implements :class:`tlfleet.bus.transport.Transport` (style.md §4, after
dora-rs'
``MockNode``), so agent and simulator tests run with no sockets; ``kill()`` simulates a process
dying (its liveliness tokens go, nothing more is delivered to or from it).
"""

from __future__ import annotations

import queue
import threading
from typing import Any

from tlfleet.bus.transport import (
    AliveCallback,
    Closeable,
    Handle,
    QueryHandler,
    RepliesCallback,
    SampleCallback,
    key_matches,
)


class FakeNetwork:
    """An in-memory bus for tests: synchronous, deterministic delivery between fake transports."""

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self._subscribers: list[tuple[FakeTransport, str, SampleCallback]] = []
        self._queryables: list[tuple[FakeTransport, str, QueryHandler, bool]] = []
        self._watchers: list[tuple[FakeTransport, str, AliveCallback]] = []
        self._tokens: list[tuple[FakeTransport, str]] = []
        self.published: list[tuple[str, bytes]] = []  # every publication, for assertions

    def transport(self, name: str = "fake") -> FakeTransport:
        return FakeTransport(self, name)

    def alive_keys(self) -> list[str]:
        with self._lock:
            return [key for _, key in self._tokens]

    # internal -------------------------------------------------------------

    def _deliver(self, key: str, payload: bytes) -> None:
        with self._lock:
            self.published.append((key, payload))
            targets = [cb for owner, expr, cb in self._subscribers
                       if not owner.closed and key_matches(expr, key)]
        for callback in targets:
            callback(key, payload)

    def _query(self, key_expr: str, payload: bytes) -> list[bytes]:
        with self._lock:
            handlers = [(h, keyed) for owner, key, h, keyed in self._queryables
                        if not owner.closed and (key_matches(key_expr, key)
                                                 or key_matches(key, key_expr))]
        replies = [handler(key_expr, payload) if keyed else handler(payload)
                   for handler, keyed in handlers]
        return [r for r in replies if r is not None]

    def _set_token(self, owner: FakeTransport, key: str, alive: bool) -> None:
        with self._lock:
            if alive:
                self._tokens.append((owner, key))
            else:
                self._tokens.remove((owner, key))
            watchers = [cb for w_owner, expr, cb in self._watchers
                        if not w_owner.closed and key_matches(expr, key)]
        for callback in watchers:
            callback(key, alive)

    def _remove(self, registry: list[Any], entry: Any) -> None:
        with self._lock:
            if entry in registry:
                registry.remove(entry)


class FakeChannel:
    """:class:`tlfleet.bus.transport.Channel` of the fake bus: a FIFO queue filled by deliveries."""

    def __init__(self) -> None:
        self._queue: queue.SimpleQueue[tuple[str, bytes] | None] = queue.SimpleQueue()
        self._handle: Closeable | None = None

    def _put(self, key: str, payload: bytes) -> None:
        self._queue.put((key, payload))

    def recv(self, timeout: float) -> tuple[str, bytes] | None:
        woken = False
        try:
            while (item := self._queue.get_nowait()) is None:
                woken = True  # a wake-up queued before the samples behind it: skip it
            return item
        except queue.Empty:
            pass
        if woken or timeout <= 0.0:
            return None
        try:
            return self._queue.get(timeout=timeout)
        except queue.Empty:
            return None

    def wake(self) -> None:
        self._queue.put(None)

    def close(self) -> None:
        if self._handle is not None:
            self._handle.close()
            self._handle = None


class FakeTransport:
    """:class:`Transport` on a :class:`FakeNetwork`; ``kill()`` simulates the process dying."""

    def __init__(self, network: FakeNetwork, name: str):
        self.network = network
        self.name = name
        self.closed = False

    def publish(self, key: str, payload: bytes) -> None:
        if not self.closed:
            self.network._deliver(key, payload)

    def subscribe(self, key_expr: str, callback: SampleCallback) -> Closeable:
        entry = (self, key_expr, callback)
        with self.network._lock:
            self.network._subscribers.append(entry)
        return Handle(lambda: self.network._remove(self.network._subscribers, entry))

    def subscribe_channel(self, key_expr: str, wake_key: str | None = None,
                          capacity: int | None = None) -> FakeChannel:
        """A :class:`tlfleet.bus.transport.Channel` of ``key_expr``: deliveries are queued for
        ``recv`` (``wake_key`` is zenoh's concern: the fake's wake-up never travels; its queue has
        no ``capacity``)."""
        del wake_key, capacity
        channel = FakeChannel()
        channel._handle = self.subscribe(key_expr, channel._put)
        return channel

    def serve(self, key: str, handler: QueryHandler, *, keyed: bool = False) -> Closeable:
        entry = (self, key, handler, keyed)
        with self.network._lock:
            self.network._queryables.append(entry)
        return Handle(lambda: self.network._remove(self.network._queryables, entry))

    def query(self, key_expr: str, payload: bytes, timeout: float) -> list[bytes]:
        del timeout  # synchronous: a missing or dead peer answers nothing at once
        return [] if self.closed else self.network._query(key_expr, payload)

    def query_async(self, key_expr: str, payload: bytes, timeout: float,
                    on_done: RepliesCallback, *, droppable: bool = False) -> None:
        del droppable  # no send queue here
        on_done(self.query(key_expr, payload, timeout))  # finished before it returns

    def declare_alive(self, key: str) -> Closeable:
        self.network._set_token(self, key, True)
        return Handle(lambda: self._drop_token(key))

    def watch_alive(self, key_expr: str, callback: AliveCallback) -> Closeable:
        entry = (self, key_expr, callback)
        with self.network._lock:
            self.network._watchers.append(entry)
            existing = [key for _, key in self.network._tokens if key_matches(key_expr, key)]
        for key in existing:
            callback(key, True)
        return Handle(lambda: self.network._remove(self.network._watchers, entry))

    def _drop_token(self, key: str) -> None:
        if (self, key) in self.network._tokens:
            self.network._set_token(self, key, False)

    def kill(self) -> None:
        """Drop everything this transport declared, as a dead process would."""
        for owner, key in list(self.network._tokens):
            if owner is self:
                self.network._set_token(self, key, False)
        self.closed = True

    def close(self) -> None:
        self.kill()
