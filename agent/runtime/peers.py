"""Stage-2 collaboration over query/reply, and who of the peers is reachable (stl-funnel.md §7.5).

One :class:`CollabLink` per STL agent process:

* serves the queryable ``robot/<own id>/collab``: decodes a ``CollabMessage``, converts it to the
  core's message, appends it to the :class:`~tlfleet.agent.runtime.inbox.CollabInbox` and replies
  ``CollabReply(accepted=True)``; a malformed payload is counted and answered
  ``CollabReply(False, reason)`` (architecture.md §2);
* sends each outgoing message by query to ``robot/<receiver>/collab``, all of a step's queries in
  flight together (:meth:`CollabLink.send_all`): in lockstep it waits for the replies (at most
  ``timeout`` [s] wall), so every message is in its receiver's inbox before the next frame; in
  realtime it does not wait (a round trip per peer would hold the agent's loop for several
  control periods: with 29 peers, ~30 ms every status period), the replies are handled when
  they come;
* keeps the set of *unreachable* peers, which the pure STL step forgets (``StepInput.unreachable``,
  so a dead partner cannot enable stage 2): a peer is unreachable while its liveliness token
  ``alive/agent/<id>`` is gone (until it is declared again), and for ``retry_after`` [s] wall
  after a query to it failed (no reply in time, or a rejection). Messages to an unreachable peer
  are not sent (a hung peer would otherwise cost a full timeout per message); the periodic status
  re-announcement (``ProtocolParams.status_period``) reaches it once it is back. Receiving a
  message from a peer does not make it reachable: a peer that can talk but not listen would
  otherwise flap between stage 2 and stage 3 at every critical event.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Sequence

from tlfleet.agent.runtime.collab import from_wire
from tlfleet.agent.runtime.inbox import CollabInbox, MalformedCounter
from tlfleet.agent.stl.messages import Message
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import ProtocolError, decode, encode
from tlfleet.bus.protocol.messages import CollabMessage, CollabReply
from tlfleet.bus.transport import Closeable, Transport

logger = logging.getLogger(__name__)
_NOBODY: frozenset[int] = frozenset()
REFUSAL_LOG_PERIOD = 1.0  # [s] wall: a sender's refused messages are logged at most this often


class CollabLink:
    """Query/reply collaboration of STL agent ``robot`` with its ``peers`` (robot ids)."""

    def __init__(self, transport: Transport, fleet: str, robot: int, peers: tuple[int, ...],
                 malformed: MalformedCounter, timeout: float = 0.25, retry_after: float = 2.0,
                 clock: Callable[[], float] = time.monotonic,
                 check: Callable[[Message], str | None] | None = None):
        self.transport = transport
        self.fleet = fleet
        self.robot = robot
        self.peers = frozenset(peers)
        self.malformed = malformed
        self.timeout = timeout
        self.inbox = CollabInbox()
        self._lock = threading.Lock()
        self.retry_after = retry_after
        self._clock = clock
        self._gone: set[int] = set()  # liveliness token disappeared
        self._failed: dict[int, float] = {}  # wall time [s] of the last failed query
        self._handles: list[Closeable] = []
        self.check = check  # the core's judgement of a message (StlAgent.collab_problem)
        self.sent = 0
        self.failed = 0
        self.received = 0
        self.refused = 0  # well-formed messages the core would not act on
        self._refusal_logged: dict[int, float] = {}  # sender -> when a refusal was last logged

    def open(self) -> None:
        """Serve the own queryable and watch the peers' liveliness tokens."""
        self._handles.append(self.transport.serve(keys.collab_all(self.fleet, self.robot),
                                                  self._on_query, keyed=True))
        self._handles.append(self.transport.watch_alive(keys.all_alive(self.fleet),
                                                        self._on_alive))

    def close(self) -> None:
        for handle in reversed(self._handles):
            handle.close()
        self._handles.clear()

    @property
    def unreachable(self) -> frozenset[int]:
        if not self._gone and not self._failed:  # every tick, nearly always: nothing to build
            return _NOBODY
        now = self._clock()
        with self._lock:
            failed = {p for p, when in self._failed.items() if now - when < self.retry_after}
            return frozenset(self._gone | failed)

    def _mark(self, peer: int, *, alive: bool | None = None, failed: bool = False,
              why: str) -> None:
        if peer not in self.peers:
            return
        with self._lock:
            if alive is True:
                self._gone.discard(peer)
                self._failed.pop(peer, None)
            elif alive is False:
                self._gone.add(peer)
            if failed:
                self._failed[peer] = self._clock()
        logger.info("robot %d: peer %d %s", self.robot, peer, why)

    # transport threads -------------------------------------------------------------------

    def _on_alive(self, key: str, alive: bool) -> None:
        parsed = keys.parse_alive(key)
        if parsed is None or parsed[0] != "agent" or not parsed[1].isdigit():
            return
        self._mark(int(parsed[1]), alive=alive,
                   why="liveliness token " + ("declared" if alive else "gone"))

    def _on_query(self, key: str, payload: bytes) -> bytes:
        """Queryable handler: never raises, always replies. The key names the sender
        (``keys.collab_from``: in a secured fleet only that robot may query it); a message
        claiming another sender is malformed, one the core would not act on (a sub-task the
        sender and this robot do not share, a funnel that is not that sub-task's) is refused
        and counted."""
        try:
            msg = decode(CollabMessage, payload)
            if not math.isfinite(msg.t):
                raise ProtocolError(f"CollabMessage.t: {msg.t} is not a finite time")
            if msg.receiver != self.robot:
                raise ProtocolError(f"CollabMessage.receiver: {msg.receiver}, this is robot "
                                    f"{self.robot}")
            sender = keys.collab_sender(key)
            if msg.sender != sender:
                raise ProtocolError(f"CollabMessage.sender: {msg.sender} on the key of "
                                    f"robot {sender}")
            core = from_wire(msg)
        except ProtocolError as exc:
            self.malformed.record(key, exc)
            return encode(CollabReply(False, str(exc)[:200]))
        problem = self.check(core) if self.check is not None else None
        if problem is not None:
            now = self._clock()
            with self._lock:
                self.refused += 1
                say = now - self._refusal_logged.get(msg.sender, -math.inf) >= REFUSAL_LOG_PERIOD
                if say:
                    self._refusal_logged[msg.sender] = now
            if say:
                logger.warning("robot %d: %s from robot %d refused: %s (%d refused so far)",
                               self.robot, msg.kind, msg.sender, problem, self.refused)
            return encode(CollabReply(False, problem[:200]))
        self.inbox.put(msg.t, msg.sender, core)
        self.received += 1
        return encode(CollabReply(True))

    # the loop ---------------------------------------------------------------------------

    def send_all(self, messages: Sequence[CollabMessage], *, wait: bool) -> int:
        """Send every message by query to its receiver, the queries in flight together.

        ``wait`` (lockstep): return once every query is finished, so each accepted message is
        in its receiver's inbox; messages to the same receiver go in *waves* (the second one
        after the first one's reply), so a receiver sees one sender's messages in send order
        whatever the transport does. Without ``wait`` (realtime) the queries are only issued:
        the loop never waits for a round trip, and the replies update the counters and the
        unreachable set from the transport thread. A message to an unreachable peer is not
        sent and counts as failed at once. Returns how many messages are known to have failed
        on return (all failures when ``wait``).
        """
        failures = 0
        waves: list[list[CollabMessage]] = []
        per_receiver: dict[int, int] = {}
        for msg in messages:
            n = per_receiver.get(msg.receiver, 0)
            per_receiver[msg.receiver] = n + 1
            if n == len(waves):
                waves.append([])
            waves[n].append(msg)
        batch = _Batch()
        for wave in waves if wait else [list(messages)]:
            unreachable = self.unreachable
            for msg in wave:
                if msg.receiver in unreachable:
                    with self._lock:
                        self.failed += 1
                    failures += 1
                    continue
                with self._lock:
                    self.sent += 1
                batch.add()
                self.transport.query_async(
                    keys.collab_from(self.fleet, msg.receiver, self.robot), encode(msg),
                    self.timeout,
                    lambda replies, msg=msg: batch.done(self._finish(msg, replies)),
                    droppable=True)
            if wait and not batch.wait(self.timeout + _DONE_GRACE):
                logger.warning("robot %d: %d collaboration queries not finished after %g s",
                               self.robot, batch.pending, self.timeout + _DONE_GRACE)
        return failures + batch.failures

    def _finish(self, msg: CollabMessage, replies: list[bytes]) -> bool:
        """The replies of one message's query (any thread): True when it was accepted."""
        reasons = []
        for raw in replies:
            try:
                reply = decode(CollabReply, raw)
            except ProtocolError as exc:
                self.malformed.record(keys.collab_from(self.fleet, msg.receiver, self.robot),
                                      exc, msg.t)
                continue
            if reply.accepted:
                return True
            reasons.append(reply.reason)
        with self._lock:
            self.failed += 1
        why = f"{msg.kind} rejected: {'; '.join(reasons)}" if reasons else f"{msg.kind}: no reply"
        self._mark(msg.receiver, failed=True, why=why)
        return False


_DONE_GRACE = 1.0  # [s] wall beyond the query timeout before a lockstep send gives up waiting


class _Batch:
    """Countdown of the queries of one ``send_all`` (their replies arrive on any thread)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self.pending = 0
        self.failures = 0

    def add(self) -> None:
        with self._cond:
            self.pending += 1

    def done(self, accepted: bool) -> None:
        with self._cond:
            self.pending -= 1
            self.failures += not accepted
            self._cond.notify_all()

    def wait(self, timeout: float) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: self.pending <= 0, timeout)
