"""The transport every tlfleet process talks through: Zenoh for real, an in-memory fake for tests.

Both implement :class:`Transport` (style.md §4, after dora-rs' ``MockNode``): publish/subscribe for
poses and commands, ``serve``/``query`` for stage-2 collaboration, liveliness tokens for presence
(architecture.md §1–§2). This module is the only place in ``agent/`` that imports zenoh, and it
applies the verified rules of stack-notes.md §0/§1: multicast scouting off unless asked, explicit
endpoints, callbacks that only hand bytes on (guarded by a ``closing`` flag, since queued
callbacks still run after ``close()``), and an explicit ``session.close()``.

Callbacks receive ``(key, payload)`` on a transport thread (zenoh) or synchronously inside the
sender's call (fake); they must be quick: store and return, decode in the process's own loop.
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from agent.protocol.keys import key_matches

logger = logging.getLogger(__name__)

SampleCallback = Callable[[str, bytes], None]
QueryHandler = Callable[[bytes], bytes | None]
RepliesCallback = Callable[[list[bytes]], None]
AliveCallback = Callable[[str, bool], None]


class Closeable(Protocol):
    def close(self) -> None: ...


class Transport(Protocol):
    """What a tlfleet process needs from its middleware."""

    def publish(self, key: str, payload: bytes) -> None: ...

    def subscribe(self, key_expr: str, callback: SampleCallback) -> Closeable: ...

    def serve(self, key: str, handler: QueryHandler) -> Closeable: ...

    def query(self, key_expr: str, payload: bytes, timeout: float) -> list[bytes]: ...

    def query_async(self, key_expr: str, payload: bytes, timeout: float,
                    on_done: RepliesCallback) -> None: ...

    def declare_alive(self, key: str) -> Closeable: ...

    def watch_alive(self, key_expr: str, callback: AliveCallback) -> Closeable: ...

    def close(self) -> None: ...


class _Handle:
    """A ``Closeable`` that runs ``undo`` once."""

    def __init__(self, undo: Callable[[], None]):
        self._undo: Callable[[], None] | None = undo

    def close(self) -> None:
        undo, self._undo = self._undo, None
        if undo is not None:
            undo()


# --------------------------------------------------------------------------- command line


@dataclass(frozen=True)
class TransportConfig:
    """Transport flags shared by every process (style.md §6)."""

    mode: str = "client"  # "client" | "peer" | "router"
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    lease_ms: int | None = None  # [ms] link lease: how fast a hung peer is declared gone
    multicast_scouting: bool = False
    extra: dict[str, Any] = field(default_factory=dict)


def add_transport_arguments(parser: argparse.ArgumentParser, default_mode: str = "client") -> None:
    group = parser.add_argument_group("transport (zenoh)")
    group.add_argument("--mode", choices=("client", "peer", "router"), default=default_mode,
                       help=f"zenoh session mode (default {default_mode})")
    group.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                       help="endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)")
    group.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                       help="endpoint to listen on, e.g. tcp/127.0.0.1:7447 (repeatable)")
    group.add_argument("--lease-ms", type=int, default=None, metavar="MS",
                       help="link lease in ms (zenoh default 10000)")
    group.add_argument("--multicast-scouting", action="store_true",
                       help="join zenoh multicast scouting (off by default)")


def transport_config(args: argparse.Namespace) -> TransportConfig:
    return TransportConfig(mode=args.mode, connect=tuple(args.connect), listen=tuple(args.listen),
                           lease_ms=args.lease_ms, multicast_scouting=args.multicast_scouting)


def open_transport(args: argparse.Namespace | TransportConfig) -> ZenohTransport:
    """Open a zenoh session from CLI flags or a ``TransportConfig``."""
    config = args if isinstance(args, TransportConfig) else transport_config(args)
    return ZenohTransport.open(config)


def install_signal_handlers(stop: threading.Event) -> None:
    """SIGINT and SIGTERM set ``stop``; the process's loop then ends and closes its session."""

    def handler(signum: int, _frame: Any) -> None:
        logger.info("signal %s: stopping", signal.Signals(signum).name)
        stop.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


# --------------------------------------------------------------------------- zenoh


class ZenohTransport:
    """:class:`Transport` over an open zenoh session (stack-notes.md §1)."""

    def __init__(self, session: Any):
        self._session = session
        self._closing = threading.Event()
        self._publishers: dict[str, Any] = {}
        self._entities: list[Any] = []

    @staticmethod
    def zenoh_config(config: TransportConfig) -> Any:
        import zenoh

        c = zenoh.Config()
        c.insert_json5("mode", json.dumps(config.mode))
        c.insert_json5("listen/endpoints", json.dumps(list(config.listen)))
        c.insert_json5("connect/endpoints", json.dumps(list(config.connect)))
        c.insert_json5("scouting/multicast/enabled", json.dumps(config.multicast_scouting))
        if config.lease_ms:
            c.insert_json5("transport/link/tx/lease", json.dumps(config.lease_ms))
        for key, value in config.extra.items():
            c.insert_json5(key, json.dumps(value))
        return c

    @classmethod
    def open(cls, config: TransportConfig) -> ZenohTransport:
        import zenoh

        return cls(zenoh.open(cls.zenoh_config(config)))

    def publish(self, key: str, payload: bytes) -> None:
        publisher = self._publishers.get(key)
        if publisher is None:
            publisher = self._session.declare_publisher(key)
            self._publishers[key] = publisher
        publisher.put(payload)

    def subscribe(self, key_expr: str, callback: SampleCallback) -> Closeable:
        closing = self._closing

        def on_sample(sample: Any) -> None:
            if closing.is_set():
                return
            try:
                callback(str(sample.key_expr), sample.payload.to_bytes())
            except Exception:
                logger.exception("subscriber callback for %s failed", key_expr)

        sub = self._session.declare_subscriber(key_expr, on_sample)
        self._entities.append(sub)
        return _Handle(sub.undeclare)

    def serve(self, key: str, handler: QueryHandler) -> Closeable:
        closing = self._closing

        def on_query(query: Any) -> None:
            if closing.is_set():
                return
            payload = query.payload.to_bytes() if query.payload is not None else b""
            try:
                reply = handler(payload)
            except Exception:
                logger.exception("queryable %s failed", key)
                return
            if reply is not None:
                query.reply(key, reply)  # own concrete key: no consolidation surprises

        queryable = self._session.declare_queryable(key, on_query)
        self._entities.append(queryable)
        return _Handle(queryable.undeclare)

    def query(self, key_expr: str, payload: bytes, timeout: float) -> list[bytes]:
        replies = []
        for reply in self._session.get(key_expr, payload=payload, timeout=timeout):
            if reply.ok is not None:
                replies.append(reply.ok.payload.to_bytes())
        return replies

    def query_async(self, key_expr: str, payload: bytes, timeout: float,
                    on_done: RepliesCallback) -> None:
        """Send a query and return at once; ``on_done(replies)`` runs on a zenoh network thread
        when the query is finished (every matching queryable answered, or ``timeout`` [s]).

        The handler is a ``Callback(indirect=False)``: it runs on the network thread, so no extra
        Python thread per query (stack-notes.md §1.7); ``on_done`` must be quick and must not
        block on the session. Its ``drop`` fires when zenoh finalises the query, also without
        any reply (no matching queryable: at once).
        """
        import zenoh

        replies: list[bytes] = []

        def on_reply(reply: Any) -> None:
            ok = reply.ok
            if ok is not None:
                replies.append(ok.payload.to_bytes())

        def on_drop() -> None:
            try:
                on_done(replies)
            except Exception:
                logger.exception("reply callback of a query on %s failed", key_expr)

        self._session.get(key_expr, zenoh.handlers.Callback(on_reply, on_drop, indirect=False),
                          payload=payload, timeout=timeout)

    def declare_alive(self, key: str) -> Closeable:
        token = self._session.liveliness().declare_token(key)
        self._entities.append(token)
        return _Handle(token.undeclare)

    def watch_alive(self, key_expr: str, callback: AliveCallback) -> Closeable:
        import zenoh

        closing = self._closing

        def on_sample(sample: Any) -> None:
            if closing.is_set():
                return
            try:
                callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)
            except Exception:
                logger.exception("liveliness callback for %s failed", key_expr)

        sub = self._session.liveliness().declare_subscriber(key_expr, on_sample, history=True)
        self._entities.append(sub)
        return _Handle(sub.undeclare)

    def close(self) -> None:
        if self._closing.is_set():
            return
        self._closing.set()
        try:
            self._session.close()
        except Exception:
            logger.exception("closing the zenoh session failed")


# --------------------------------------------------------------------------- fake


class FakeNetwork:
    """An in-memory bus for tests: synchronous, deterministic delivery between fake transports."""

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self._subscribers: list[tuple[FakeTransport, str, SampleCallback]] = []
        self._queryables: list[tuple[FakeTransport, str, QueryHandler]] = []
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
            handlers = [h for owner, key, h in self._queryables
                        if not owner.closed and key_matches(key_expr, key)]
        replies = [handler(payload) for handler in handlers]
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
        return _Handle(lambda: self.network._remove(self.network._subscribers, entry))

    def serve(self, key: str, handler: QueryHandler) -> Closeable:
        entry = (self, key, handler)
        with self.network._lock:
            self.network._queryables.append(entry)
        return _Handle(lambda: self.network._remove(self.network._queryables, entry))

    def query(self, key_expr: str, payload: bytes, timeout: float) -> list[bytes]:
        del timeout  # synchronous: a missing or dead peer answers nothing at once
        return [] if self.closed else self.network._query(key_expr, payload)

    def query_async(self, key_expr: str, payload: bytes, timeout: float,
                    on_done: RepliesCallback) -> None:
        on_done(self.query(key_expr, payload, timeout))  # finished before it returns

    def declare_alive(self, key: str) -> Closeable:
        self.network._set_token(self, key, True)
        return _Handle(lambda: self._drop_token(key))

    def watch_alive(self, key_expr: str, callback: AliveCallback) -> Closeable:
        entry = (self, key_expr, callback)
        with self.network._lock:
            self.network._watchers.append(entry)
            existing = [key for _, key in self.network._tokens if key_matches(key_expr, key)]
        for key in existing:
            callback(key, True)
        return _Handle(lambda: self.network._remove(self.network._watchers, entry))

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
