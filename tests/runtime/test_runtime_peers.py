"""CollabLink.send_all: queries in flight together, waves per receiver in lockstep, no waiting in
realtime (stl-funnel.md §7.5; architecture.md §3)."""

from __future__ import annotations

import threading

from tlfleet.agent.runtime.inbox import MalformedCounter
from tlfleet.agent.runtime.peers import CollabLink
from tlfleet.bus.protocol.codec import decode, encode
from tlfleet.bus.protocol.messages import CollabMessage, CollabReply

FLEET = "peers"


class DeferredTransport:
    """Records every query and finishes it only when the test says so (as zenoh would, from
    another thread)."""

    def __init__(self) -> None:
        self.lock = threading.Condition()
        self.issued: list[tuple[int, str]] = []  # (receiver, kind) in issue order
        self.open: dict[int, list] = {}  # receiver -> on_done callbacks not finished yet
        self.blocking: list[str] = []  # queries sent without droppable (waiting on a full link)

    def query_async(self, key_expr, payload, timeout, on_done, *, droppable=False):
        msg = decode(CollabMessage, payload)
        with self.lock:
            if not droppable:
                self.blocking.append(key_expr)
            self.issued.append((msg.receiver, msg.kind))
            self.open.setdefault(msg.receiver, []).append(on_done)
            self.lock.notify_all()

    def wait_issued(self, n: int) -> None:
        with self.lock:
            assert self.lock.wait_for(lambda: len(self.issued) >= n, 10.0)

    def answer(self, receiver: int, replies: tuple[CollabReply, ...] = (CollabReply(True),)):
        """Finish the oldest open query to ``receiver`` with ``replies`` (none: a timeout)."""
        with self.lock:
            on_done = self.open[receiver].pop(0)
        on_done([encode(r) for r in replies])


def message(kind: str, receiver: int) -> CollabMessage:
    return CollabMessage(kind, 3, receiver, 1.0, 0)


def test_lockstep_sends_in_waves_and_waits_for_every_reply():
    """Robot 4 gets two messages: the second is issued only after the first was answered, while
    the message to robot 5 is in flight together with the first one."""
    transport = DeferredTransport()
    link = CollabLink(transport, FLEET, 3, (4, 5), MalformedCounter("agent/3"))
    result = {}
    sender = threading.Thread(target=lambda: result.setdefault("failures", link.send_all(
        (message("request", 4), message("status", 5), message("status", 4)), wait=True)))
    sender.start()
    transport.wait_issued(2)
    assert transport.issued == [(4, "request"), (5, "status")]
    transport.answer(5, replies=())  # no reply at all from 5: a timeout
    transport.answer(4)
    transport.wait_issued(3)
    assert transport.issued[2] == (4, "status")
    assert sender.is_alive()  # still waiting for the second wave
    transport.answer(4)
    sender.join(10.0)
    assert not sender.is_alive() and result["failures"] == 1
    assert (link.sent, link.failed) == (3, 1)
    assert link.unreachable == frozenset({5})
    # never a query that waits for room on a congested link: the loop waits for the
    # replies, bounded by the timeout, and for nothing else
    assert transport.blocking == []
