"""The Zenoh implementation of :class:`tlfleet.bus.transport.Transport` (docs/stack-notes.md §0/§1).

This module is the only place in the tree that imports zenoh. It applies the verified rules of
docs/stack-notes.md: multicast scouting off unless asked, explicit endpoints, callbacks that only
hand bytes on (guarded by a ``closing`` flag, since queued callbacks still run after
``close()``), and an explicit ``session.close()``.
"""

from __future__ import annotations

import json
import logging
import os
import threading
import time
from typing import Any

from tlfleet.bus.transport import (
    AliveCallback,
    Closeable,
    Handle,
    QueryHandler,
    RepliesCallback,
    SampleCallback,
    TransportConfig,
    note_runtime_set_here,
)
from tlfleet.bus.zenoh import config as zenoh_config

logger = logging.getLogger(__name__)


def init_log(spec: str) -> None:
    """Install zenoh's own log subscriber (Rust ``tracing``, written to standard output) with the
    filter ``spec`` (``RUST_LOG`` syntax) unless ``RUST_LOG`` is set; once per process."""
    import zenoh

    zenoh.init_log_from_env_or(spec)


class ZenohTransport:
    """:class:`Transport` over an open zenoh session (docs/stack-notes.md §1)."""

    def __init__(self, session: Any, direct_callbacks: bool = False,
                 block_when_congested: bool = False):
        self._session = session
        self._direct = direct_callbacks
        self._publisher_options: dict[str, Any] = {}
        if block_when_congested:
            import zenoh

            self._publisher_options["congestion_control"] = zenoh.CongestionControl.BLOCK
        self._closing = threading.Event()
        self._publishers: dict[str, Any] = {}
        self._entities: list[Any] = []

    @staticmethod
    def zenoh_config(config: TransportConfig) -> Any:
        """The session's zenoh config: the ``--zenoh-config`` file if any, tlfleet's own
        settings on top (:mod:`tlfleet.bus.zenoh.config`); ``ZenohConfigError`` names the file and
        key zenoh refuses."""
        import zenoh

        def refused(c: Any, key: str, value: str) -> str | None:
            try:
                c.insert_json5(key, value)
            except Exception as exc:  # zenoh.ZError
                return str(exc)
            return None

        text = None
        if config.zenoh_config is None:
            c = zenoh.Config()
        else:
            text = zenoh_config.read_text(config.zenoh_config)
            try:
                c = zenoh.Config.from_json5(text)
            except Exception as exc:  # zenoh.ZError: zenoh says what, not where
                raise zenoh_config.refusal(
                    config.zenoh_config, text, str(exc),
                    lambda key, value: refused(zenoh.Config(), key, value)) from None
        for key, value in zenoh_config.own_settings(config, zenoh_config.file_keys(text)):
            reason = refused(c, key, json.dumps(value))
            if reason is not None:
                raise zenoh_config.ZenohConfigError(
                    config.zenoh_config or "(tlfleet's settings)", key,
                    zenoh_config.clean_reason(reason))
        return c

    @staticmethod
    def apply_runtime(config: TransportConfig) -> None:
        """Set ``ZENOH_RUNTIME`` from ``config.runtime`` unless the environment already has one
        (zenoh reads it when the process's first session opens)."""
        if config.runtime is not None and "ZENOH_RUNTIME" not in os.environ:
            os.environ["ZENOH_RUNTIME"] = config.runtime
            note_runtime_set_here(config.runtime)  # not for the children (child_environment)

    @classmethod
    def open(cls, config: TransportConfig) -> ZenohTransport:
        import zenoh

        cls.apply_runtime(config)
        return cls(zenoh.open(cls.zenoh_config(config)), config.direct_callbacks,
                   config.block_when_congested)

    def publish(self, key: str, payload: bytes) -> None:
        publisher = self._publishers.get(key)
        if publisher is None:
            publisher = self._session.declare_publisher(key, **self._publisher_options)
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

        if self._direct:
            import zenoh

            sub = self._session.declare_subscriber(
                key_expr, zenoh.handlers.Callback(on_sample, indirect=False))
        else:
            sub = self._session.declare_subscriber(key_expr, on_sample)
        self._entities.append(sub)
        return Handle(sub.undeclare)

    def subscribe_channel(self, key_expr: str, wake_key: str | None = None,
                          capacity: int | None = None) -> ZenohChannel:
        """A :class:`tlfleet.bus.transport.Channel` of ``key_expr``; ``wake_key``: the
        concrete key matching it that ``wake()`` uses (default ``key_expr`` itself);
        ``capacity``: samples queued at most (default :attr:`ZenohChannel.CAPACITY`)."""
        channel = ZenohChannel(self._session, key_expr, wake_key, capacity)
        self._entities.append(channel)
        return channel

    def serve(self, key: str, handler: QueryHandler, *, keyed: bool = False) -> Closeable:
        """Answer queries on ``key`` with ``handler(payload)`` (``keyed``: ``handler(query key,
        payload)``; None: no reply); a reply has its query's congestion control (zenoh 1.10
        ignores one given to ``reply``)."""
        closing = self._closing

        def on_query(query: Any) -> None:
            if closing.is_set():
                return
            payload = query.payload.to_bytes() if query.payload is not None else b""
            asked = str(query.key_expr)
            if keyed and ("*" in asked or "$" in asked):
                return  # a wildcard query names no one key: nothing to answer for
            try:
                reply = handler(asked, payload) if keyed else handler(payload)
            except Exception:
                logger.exception("queryable %s failed", key)
                return
            if reply is not None:
                # a concrete key: the declared one, or for a wildcard queryable the key asked
                query.reply(asked if keyed else key, reply)

        queryable = self._session.declare_queryable(key, on_query)
        self._entities.append(queryable)
        return Handle(queryable.undeclare)

    def query(self, key_expr: str, payload: bytes, timeout: float) -> list[bytes]:
        replies = []
        for reply in self._session.get(key_expr, payload=payload, timeout=timeout):
            if reply.ok is not None:
                replies.append(reply.ok.payload.to_bytes())
        return replies

    def query_async(self, key_expr: str, payload: bytes, timeout: float,
                    on_done: RepliesCallback, *, droppable: bool = False) -> None:
        """Send a query and return; ``on_done(replies)`` runs on a zenoh network thread
        when the query is finished (every matching queryable answered, or ``timeout`` [s]).

        A query's congestion control is BLOCK by default: ``session.get`` waits for room in the
        link's send queue, and a link a partition blackholed can hold it until zenoh closes the
        link (``wait_before_close``: 5 s by default, the lease with ``--lease-ms``). With
        ``droppable`` the query uses DROP instead: on a congested link it is dropped after
        ``wait_before_drop`` (1 ms by default) and finishes, at its timeout, without replies —
        so the call never holds its caller: an agent's collaboration queries to a partitioned
        partner must not hold its control loop, and a lockstep loop waits for their
        replies at most the query timeout.

        The handler is a ``Callback(indirect=False)``: it runs on the network thread, so no extra
        Python thread per query (docs/stack-notes.md §1.7); ``on_done`` must be quick and must not
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
                          payload=payload, timeout=timeout,
                          **({"congestion_control": zenoh.CongestionControl.DROP}
                             if droppable else {}))

    def declare_alive(self, key: str) -> Closeable:
        token = self._session.liveliness().declare_token(key)
        self._entities.append(token)
        return Handle(token.undeclare)

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
        return Handle(sub.undeclare)

    def close(self) -> None:
        if self._closing.is_set():
            return
        self._closing.set()
        try:
            self._session.close()
        except Exception:
            logger.exception("closing the zenoh session failed")


class ZenohChannel:
    """:class:`tlfleet.bus.transport.Channel` on a ``FifoChannel`` subscriber.

    ``recv`` blocks in zenoh's own ``recv`` on the calling thread, so a sample wakes that thread
    directly. zenoh's ``recv`` has no timeout: ``wake()`` puts a session-local DELETE on the key
    (``allowed_destination=SESSION_LOCAL``: it reaches only this session's subscribers, never
    the network), and a timer thread calls it once a blocked ``recv`` is past its deadline. The
    timer sleeps until the deadline of the ``recv`` it finds blocked (then, if a newer ``recv``
    has a later one, until that), and :data:`tlfleet.bus.transport.CHANNEL_TICK` when it finds none:
    a reader that blocks in slices of T s is visited every T s, not 1 / CHANNEL_TICK times a
    second (an agent's timer thread woke 20 times a second, ≈ 70 µs of CPU
    each). The timer starts with the first ``recv`` that may block: a channel only polled with
    ``recv(0.0)`` (the coordinator's recorder) has none.
    """

    CAPACITY = 1024  # samples queued at most: a full channel holds up zenoh's reader of the link

    def __init__(self, session: Any, key: str, wake_key: str | None = None,
                 capacity: int | None = None):
        import zenoh

        self._session = session
        self._key = wake_key or key
        self._local = zenoh.Locality.SESSION_LOCAL
        self._delete = zenoh.SampleKind.DELETE
        self._sub = session.declare_subscriber(
            key, zenoh.handlers.FifoChannel(capacity or self.CAPACITY))
        self._deadline: float | None = None  # monotonic [s] of the blocked recv, if any
        self._closed = threading.Event()
        self._timer = threading.Thread(target=self._tick, name=f"channel-timer {key}",
                                       daemon=True)
        self._timing = False

    def _tick(self) -> None:
        from tlfleet.bus.transport import CHANNEL_TICK

        pause = CHANNEL_TICK
        while not self._closed.wait(pause):
            deadline = self._deadline
            if deadline is None:  # no recv blocked: look again later
                pause = CHANNEL_TICK
                continue
            pause = deadline - time.monotonic()
            if pause <= 0.0:
                self._deadline = None
                self.wake()
                pause = CHANNEL_TICK

    def recv(self, timeout: float) -> tuple[str, bytes] | None:
        woken = False
        while (sample := self._sub.try_recv()) is not None:
            if sample.kind != self._delete:
                return str(sample.key_expr), sample.payload.to_bytes()
            woken = True  # a wake-up queued before the samples behind it: skip it
        if woken or timeout <= 0.0 or self._closed.is_set():
            return None
        if not self._timing:  # the first recv that may block (one thread recvs a channel)
            self._timing = True
            self._timer.start()
        self._deadline = time.monotonic() + timeout
        try:
            sample = self._sub.recv()
        except Exception:  # undeclared under a blocked recv: the channel is closed
            if self._closed.is_set():
                return None
            raise
        finally:
            self._deadline = None
        if sample.kind == self._delete:
            return None
        return str(sample.key_expr), sample.payload.to_bytes()

    def wake(self) -> None:
        try:
            self._session.delete(self._key, allowed_destination=self._local)
        except Exception:  # a closed session: nothing is blocked on it any more
            logger.debug("waking the channel of %s failed", self._key, exc_info=True)

    def close(self) -> None:
        self.undeclare()

    def undeclare(self) -> None:
        if self._closed.is_set():
            return
        self._closed.set()
        try:
            self._sub.undeclare()
        except Exception:
            logger.debug("undeclaring the channel of %s failed", self._key, exc_info=True)


def open_transport(config: TransportConfig) -> ZenohTransport:
    """Open a zenoh session from a :class:`TransportConfig`."""
    return ZenohTransport.open(config)


def check_config(config: TransportConfig) -> None:
    """Build the session config without opening it: a bad ``--zenoh-config`` raises
    ``ZenohConfigError`` (file and key named) before anything starts."""
    ZenohTransport.zenoh_config(config)
