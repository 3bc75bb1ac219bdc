"""The transport interface of every tlfleet process, and its typed configuration.

:class:`Transport` (style.md §4, after dora-rs' ``MockNode``) is what a process needs from its
middleware: publish/subscribe for poses and commands, ``serve``/``query`` for stage-2
collaboration, liveliness tokens for presence (architecture.md §1–§2). Two implementations share
it: :class:`tlfleet.bus.zenoh.transport.ZenohTransport` for real (opened by
:func:`tlfleet.bus.zenoh.transport.open_transport`) and :class:`tlfleet.bus.fake.FakeTransport` for
tests.

Callbacks receive ``(key, payload)`` on a transport thread (zenoh) or synchronously inside the
sender's call (fake); they must be quick: store and return, decode in the process's own loop.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

SampleCallback = Callable[[str, bytes], None]
QueryHandler = Callable[..., bytes | None]  # (payload) or, served ``keyed``, (key, payload)
RepliesCallback = Callable[[list[bytes]], None]
AliveCallback = Callable[[str, bool], None]


class Closeable(Protocol):
    def close(self) -> None: ...


class Channel(Protocol):
    """The samples of one concrete key, read by the thread that handles them.

    A callback subscriber hands every sample from the transport's thread to the process's loop
    (a thread wake-up per sample); a channel is read by the loop itself. ``recv(timeout)``
    returns the oldest queued ``(key, payload)``, or ``None`` when ``timeout`` [s] passed
    (at most :data:`CHANNEL_TICK` late on a zenoh channel) or ``wake()`` was
    called (from any thread); ``recv(0.0)`` never blocks. A wake-up queued before samples is
    skipped (the caller is awake anyway). A sample without payload (a zenoh DELETE) reads as a
    wake-up. Created by ``subscribe_channel(key_expr, wake_key=None, capacity=None)`` of the
    transports that have one (``wake_key``: a concrete key matching ``key_expr``, when that has
    wildcards; ``capacity``: samples queued at most, ``None`` for the transport's default — a
    full zenoh channel holds up the link it is read from, so a reader that drains only now and
    then, like the coordinator's recorder, asks for room for seconds of samples).
    """

    def recv(self, timeout: float) -> tuple[str, bytes] | None: ...

    def wake(self) -> None: ...

    def close(self) -> None: ...


#: [s] how often a zenoh channel's timer thread looks for a blocked ``recv`` while it finds none
#: (a ``recv`` it finds blocked is woken at its deadline)
CHANNEL_TICK = 0.05


class Transport(Protocol):
    """What a tlfleet process needs from its middleware."""

    def publish(self, key: str, payload: bytes) -> None: ...

    def subscribe(self, key_expr: str, callback: SampleCallback) -> Closeable: ...

    # ``keyed``: the handler gets the query's concrete key too, ``handler(key, payload)`` (a
    # queryable on a wildcard learns which key was asked: the collaboration keys name the sender)
    def serve(self, key: str, handler: QueryHandler, *, keyed: bool = False) -> Closeable: ...

    def query(self, key_expr: str, payload: bytes, timeout: float) -> list[bytes]: ...

    # ``droppable``: on a link whose send queue is full, drop the query after at most a
    # millisecond instead of waiting for room (zenoh's congestion control DROP; its replies
    # follow the query's). A query that must not hold its caller (an agent's control loop,
    # whose partner may be cut off) is droppable: a dropped query is a query without replies, which
    # its sender already handles; the default waits, up to the link's close
    # (tlfleet.bus.zenoh.config).
    def query_async(self, key_expr: str, payload: bytes, timeout: float,
                    on_done: RepliesCallback, *, droppable: bool = False) -> None: ...

    def declare_alive(self, key: str) -> Closeable: ...

    def watch_alive(self, key_expr: str, callback: AliveCallback) -> Closeable: ...

    def close(self) -> None: ...


class Handle:
    """A ``Closeable`` that runs ``undo`` once."""

    def __init__(self, undo: Callable[[], None]):
        self._undo: Callable[[], None] | None = undo

    def close(self) -> None:
        undo, self._undo = self._undo, None
        if undo is not None:
            undo()


#: worker threads of zenoh's receive runtime in every tlfleet process (zenoh's default: 2). zenoh
#: drops a link it lost on an RX worker, and the socket's close(2) blocks there for as long as
#: unacknowledged data is left, up to zenoh's SO_LINGER of 10 s (zenoh-link-tcp and -tls). A
#: link lost to a partition (a blackhole, not a reset) holds its worker until the partition
#: heals or 10 s pass; with 2 workers, a peer that lost both of its links to a partitioned peer
#: received nothing from anyone, the simulator's frames included (the partner
#: partition stalled a lockstep fleet for the partition's length; gdb showed rx-0 and rx-1 in
#: close(2)). With 8, a process keeps receiving while up to 6 of its links are held so; the
#: extra workers are parked threads when idle.
RX_WORKERS = 8
#: the ``ZENOH_RUNTIME`` of every tlfleet process unless its configuration or environment says
#: otherwise (:attr:`TransportConfig.runtime`)
DEFAULT_RUNTIME = f"(rx: (worker_threads: {RX_WORKERS}))"

#: the ``ZENOH_RUNTIME`` value this process put into its own environment for its session
#: (``ZenohTransport.apply_runtime``); None when it set none
_runtime_set_here: str | None = None


def note_runtime_set_here(value: str) -> None:
    """Record that this process set ``ZENOH_RUNTIME = value`` for its own session."""
    global _runtime_set_here
    _runtime_set_here = value


def child_environment(env: Mapping[str, str]) -> dict[str, str]:
    """``env`` for a child process, without the ``ZENOH_RUNTIME`` this process set for its own
    session: zenoh reads the variable once per process and an environment value wins over a
    process's own choice, so a coordinator's would otherwise decide every child's runtime (the
    lockstep peers' ``--zenoh-runtime minimal``). A value the user set is passed on."""
    out = dict(env)
    if _runtime_set_here is not None and out.get("ZENOH_RUNTIME") == _runtime_set_here:
        del out["ZENOH_RUNTIME"]
    return out


#: zenoh's runtime threads (``ZENOH_RUNTIME``) for a process that moves ~100 small messages a
#: second: one async worker, and every other runtime (rx, tx, net, acc) handed over to it. A
#: default session runs 7 OS threads (+1 per callback entity); each received sample then wakes
#: 3–4 of them. Measured with the real fleet (``bench/runtime_bench.py``): less CPU per
#: tick in every process (router −25…40 %). Opt-in, not the default: under a flood of malformed
#: payloads (10 000 per key, tests/security) a router with one worker fell behind and closed its
#: clients' transports ("Unable to push non droppable network message"), taking the fleet down.
#: Its single worker also receives: one link lost to a partition (RX_WORKERS) stops the process,
#: so tlfleet uses it only for the sim and agents of a run over loopback peer links (lockstep
#: or realtime, tlfleet.coordinator.run.peer_links), which no fault or partition reaches.
MINIMAL_RUNTIME = ("(app: (worker_threads: 1), rx: (handover: app), tx: (handover: app), "
                   "net: (handover: app), acc: (handover: app))")


@dataclass(frozen=True)
class TransportConfig:
    """How a process opens its session: the transport flags every process shares (style.md §6).

    ``runtime``: the ``ZENOH_RUNTIME`` value set in this process before its (first) session opens
    (zenoh reads it once per process; an existing ``ZENOH_RUNTIME`` in the environment wins);
    the default, :data:`DEFAULT_RUNTIME`, is zenoh's thread pools with :data:`RX_WORKERS`
    receive workers; ``None`` keeps zenoh's own; :data:`MINIMAL_RUNTIME` saves CPU.
    ``direct_callbacks``: subscriber callbacks run on zenoh's network thread
    (``Callback(indirect=False)``) instead of a Python thread per subscriber, saving one thread
    wake-up per sample; they must then be quick and never block.
    ``block_when_congested``: this session's publications block while a link's send queue is
    full (zenoh ``CongestionControl.BLOCK``, carried with each sample to every hop) instead of
    being dropped after zenoh's ``wait_before_drop`` (1 ms; 50 ms for a fragmented sample). Off
    for the fleet's processes, so a slow receiver never holds up a robot's loop; for tools and
    tests that must not lose a sample (the fuzz test's intruder counts what every receiver got).
    """

    mode: str = "client"  # "client" | "peer" | "router"
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    lease_ms: int | None = None  # [ms] link lease: how fast a hung peer is declared gone
    multicast_scouting: bool = False
    extra: dict[str, Any] = field(default_factory=dict)  # zenoh config path -> JSON value
    runtime: str | None = DEFAULT_RUNTIME
    direct_callbacks: bool = False
    block_when_congested: bool = False
    zenoh_config: Path | None = None  # a zenohd-style JSON5 file under these settings
    #                                   (tlfleet.bus.zenoh.config)


def key_matches(key_expr: str, key: str) -> bool:
    """Zenoh key-expression matching of a concrete ``key``: ``*`` is one chunk, ``**`` any number
    of chunks (zero included)."""
    return _match(key_expr.split("/"), key.split("/"))


def _match(pattern: list[str], chunks: list[str]) -> bool:
    if not pattern:
        return not chunks
    head, rest = pattern[0], pattern[1:]
    if head == "**":
        return any(_match(rest, chunks[i:]) for i in range(len(chunks) + 1))
    if not chunks:
        return False
    return (head == "*" or head == chunks[0]) and _match(rest, chunks[1:])
