"""Transport: key matching, the fake network's semantics, and the same calls over real zenoh on
loopback (multicast scouting off, explicit tcp/127.0.0.1 endpoints)."""

from __future__ import annotations

import threading

import pytest
from process_helpers import free_port
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.transport import TransportConfig, key_matches
from tlfleet.bus.zenoh.transport import ZenohTransport


@pytest.mark.parametrize(("expr", "key", "expected"), [
    ("tlfleet/s/mocap", "tlfleet/s/mocap", True),
    ("tlfleet/s/mocap", "tlfleet/s/clock", False),
    ("tlfleet/s/robot/*/cmd", "tlfleet/s/robot/3/cmd", True),
    ("tlfleet/s/robot/*/cmd", "tlfleet/s/robot/3/status", False),
    ("tlfleet/s/robot/*/cmd", "tlfleet/s/robot/cmd", False),
    ("tlfleet/s/alive/**", "tlfleet/s/alive/agent/3", True),
    ("tlfleet/s/alive/**", "tlfleet/s/alive", True),
    ("tlfleet/**/cmd", "tlfleet/s/robot/3/cmd", True),
    ("tlfleet/**/cmd", "tlfleet/s/robot/3/status", False),
    ("tlfleet/s/*", "tlfleet/s/robot/3", False),
])
def test_key_matches(expr, key, expected):
    assert key_matches(expr, key) is expected


def test_fake_pub_sub_query_and_liveliness():
    net = FakeNetwork()
    a, b = net.transport("a"), net.transport("b")
    got: list[tuple[str, bytes]] = []
    b.subscribe("f/robot/*/cmd", lambda k, p: got.append((k, p)))
    a.publish("f/robot/3/cmd", b"x")
    a.publish("f/robot/3/status", b"y")
    assert got == [("f/robot/3/cmd", b"x")]

    b.serve("f/robot/4/collab", lambda p: b"ok:" + p)
    assert a.query("f/robot/4/collab", b"req", timeout=1.0) == [b"ok:req"]
    assert a.query("f/robot/5/collab", b"req", timeout=1.0) == []

    seen: list[tuple[str, bool]] = []
    b.declare_alive("f/alive/agent/4")
    a.watch_alive("f/alive/**", lambda k, alive: seen.append((k, alive)))
    assert seen == [("f/alive/agent/4", True)]  # history: existing tokens at once
    b.kill()
    assert seen[-1] == ("f/alive/agent/4", False)
    assert a.query("f/robot/4/collab", b"req", timeout=1.0) == []  # dead peer answers nothing
    a.publish("f/robot/3/cmd", b"z")
    assert got[-1] == ("f/robot/3/cmd", b"x")  # its subscriber died with it



@pytest.fixture
def loopback_pair():
    """Two client sessions ``(a, b)`` through a router on a free loopback port; all closed after."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = ZenohTransport.open(TransportConfig(mode="router", listen=(endpoint,)))
    a = ZenohTransport.open(TransportConfig(mode="client", connect=(endpoint,)))
    b = ZenohTransport.open(TransportConfig(mode="client", connect=(endpoint,)))
    try:
        yield a, b
    finally:
        for t in (a, b, router):
            t.close()


@pytest.mark.system
def test_zenoh_round_trip_on_loopback(loopback_pair):
    a, b = loopback_pair
    arrived = threading.Event()
    payloads: list[bytes] = []

    def on_cmd(key: str, payload: bytes) -> None:
        payloads.append(payload)
        arrived.set()

    b.subscribe("t/robot/*/cmd", on_cmd)
    b.serve("t/robot/2/collab", lambda p: b"ack " + p)
    alive = threading.Event()
    gone = threading.Event()
    a.watch_alive("t/alive/**", lambda k, up: (alive if up else gone).set())
    token = b.declare_alive("t/alive/agent/2")
    assert alive.wait(5.0)
    # a subscriber declared by a remote session may take a moment to propagate
    for _ in range(50):
        a.publish("t/robot/2/cmd", b"go")
        if arrived.wait(0.1):
            break
    assert payloads and payloads[0] == b"go"
    assert a.query("t/robot/2/collab", b"help", timeout=2.0) == [b"ack help"]
    token.close()
    assert gone.wait(5.0)


def test_fake_query_async_is_finished_before_it_returns():
    net = FakeNetwork()
    a, b = net.transport("a"), net.transport("b")
    b.serve("f/robot/4/collab", lambda p: b"ok:" + p)
    done: list[list[bytes]] = []
    a.query_async("f/robot/4/collab", b"req", 1.0, done.append)
    a.query_async("f/robot/5/collab", b"req", 1.0, done.append)
    assert done == [[b"ok:req"], []]


@pytest.mark.system
def test_zenoh_query_async_returns_before_the_reply(loopback_pair):
    """The asker is not held while the queryable works; ``on_done`` gets the replies later, and
    a query nobody serves finishes with none."""
    a, b = loopback_pair
    release = threading.Event()
    try:
        def slow(payload: bytes) -> bytes:
            release.wait(10.0)
            return b"ack " + payload

        b.serve("t/robot/2/collab", slow)
        assert a.query("t/robot/9/collab", b"x", timeout=0.5) == []
        results: dict[str, list[bytes]] = {}
        finished = {name: threading.Event() for name in ("served", "nobody")}

        def on_done(name: str):
            return lambda replies: (results.setdefault(name, replies), finished[name].set())

        release.set()
        for _ in range(50):  # the remote queryable may take a moment to propagate
            if a.query("t/robot/2/collab", b"probe", timeout=0.1):
                break
        release.clear()
        a.query_async("t/robot/2/collab", b"help", 5.0, on_done("served"))
        a.query_async("t/robot/9/collab", b"help", 5.0, on_done("nobody"))
        assert finished["nobody"].wait(5.0) and results["nobody"] == []
        assert not finished["served"].is_set()  # the queryable is still holding its reply
        release.set()
        assert finished["served"].wait(5.0) and results["served"] == [b"ack help"]
    finally:
        release.set()  # let a held queryable answer before the sessions close


@pytest.mark.system
def test_zenoh_channel_is_read_by_the_calling_thread(loopback_pair):
    """A FIFO channel subscriber: samples in order, recv(timeout) returns None on
    time, wake() from another thread ends a blocked recv, and the wake-up (a session-local
    DELETE) never reaches another session."""
    import time

    a, b = loopback_pair
    channel = a.subscribe_channel("test/channel")
    other = b.subscribe_channel("test/channel")
    deadline = time.monotonic() + 10
    got = None
    while got is None and time.monotonic() < deadline:  # until the subscription is known
        b.publish("test/channel", b"hello")
        got = channel.recv(0.2)
    assert got == ("test/channel", b"hello")
    while channel.recv(0.1) is not None:  # the other hellos
        pass
    for payload in (b"1", b"2", b"3"):
        b.publish("test/channel", payload)
    assert [channel.recv(2.0) for _ in range(3)] == [("test/channel", p) for p in
                                                       (b"1", b"2", b"3")]
    began = time.monotonic()
    assert channel.recv(0.1) is None
    assert 0.09 <= time.monotonic() - began < 2.0
    timer = threading.Timer(0.1, channel.wake)
    timer.start()
    began = time.monotonic()
    assert channel.recv(10.0) is None and time.monotonic() - began < 5.0
    timer.join()
    time.sleep(0.2)
    while (item := other.recv(0.0)) is not None:  # b's own hellos came back to it
        assert item[1] != b""
    # the timer thread starts with the first recv that may block: a polled channel has none
    assert channel._timer.is_alive() and not other._timer.is_alive()
    channel.close()
    other.close()


class _CountingEvent(threading.Event):
    """A ``threading.Event`` that records every ``wait`` timeout: the channel timer's sleeps."""

    def __init__(self):
        super().__init__()
        self.waits: list[float | None] = []

    def wait(self, timeout=None):
        self.waits.append(timeout)
        return super().wait(timeout)


@pytest.mark.system
def test_zenoh_channel_timer_wakes_at_the_deadline_and_sleeps_through_a_steady_reader(
        loopback_pair):
    """Round 17: a blocked ``recv`` is woken at its deadline (at most ``CHANNEL_TICK``
    late), and while samples keep a reader that blocks in 0.25 s slices busy, the timer sleeps
    until each slice's deadline instead of looking every ``CHANNEL_TICK`` (20 times a second)."""
    import time

    from tlfleet.bus.transport import CHANNEL_TICK

    a, b = loopback_pair
    channel = a.subscribe_channel("test/timer")
    channel._closed = timer_sleeps = _CountingEvent()  # before the timer thread starts
    try:
        began = time.monotonic()
        assert channel.recv(0.3) is None
        assert 0.29 <= time.monotonic() - began < 0.3 + CHANNEL_TICK + 1.0
        got, deadline = None, time.monotonic() + 10
        while got is None and time.monotonic() < deadline:  # until the subscription is known
            b.publish("test/timer", b"x")
            got = channel.recv(0.05)
        stop = threading.Event()

        def publish_every_10_ms() -> None:
            for _ in range(500):  # at most 5 s
                if stop.wait(0.01):
                    return
                b.publish("test/timer", b"x")

        publisher = threading.Thread(target=publish_every_10_ms, daemon=True)
        publisher.start()
        time.sleep(0.1)
        before, began, received = len(timer_sleeps.waits), time.monotonic(), 0
        while time.monotonic() - began < 1.0 and received < 1000:
            received += channel.recv(0.25) is not None
        looks = len(timer_sleeps.waits) - before
        stop.set()
        publisher.join(5.0)
        assert received >= 20  # the reader was kept busy
        assert looks <= 8, looks  # 1 s / 0.25 s and a margin; a fixed 50 ms tick looks 20 times
    finally:
        channel.close()


class _SpySession:
    """Records what ZenohTransport passes to zenoh's ``get``."""

    def __init__(self) -> None:
        self.gets: list[dict] = []

    def get(self, key_expr, handler=None, **options):
        self.gets.append(options)


class _SpyPublisherSession:
    """Records what ZenohTransport passes to zenoh's ``declare_publisher``."""

    def __init__(self) -> None:
        self.declared: list[tuple[str, dict]] = []
        self.puts: list[tuple[str, bytes]] = []

    def declare_publisher(self, key_expr, **options):
        self.declared.append((key_expr, options))
        puts = self.puts

        class Publisher:
            def put(self, payload):
                puts.append((key_expr, payload))

        return Publisher()


def test_block_when_congested_declares_blocking_publishers_once_per_key():
    """A session opened with ``block_when_congested`` (the fuzz test's intruder) publishes with
    CongestionControl.BLOCK; the fleet's default leaves zenoh's (DROP) in place."""
    import zenoh

    blocking, default = _SpyPublisherSession(), _SpyPublisherSession()
    for session, block in ((blocking, True), (default, False)):
        transport = ZenohTransport(session, block_when_congested=block)
        transport.publish("t/a", b"1")
        transport.publish("t/a", b"2")
        transport.publish("t/b", b"3")
        assert session.puts == [("t/a", b"1"), ("t/a", b"2"), ("t/b", b"3")]
    assert blocking.declared == [("t/a", {"congestion_control": zenoh.CongestionControl.BLOCK}),
                                 ("t/b", {"congestion_control": zenoh.CongestionControl.BLOCK})]
    assert default.declared == [("t/a", {}), ("t/b", {})]


def test_droppable_queries_use_congestion_control_drop():
    """A query's default congestion control (BLOCK) can hold the caller until zenoh
    closes a blackholed link; ``droppable`` asks zenoh to drop instead (the replies follow the
    query's). The default is kept for every other query (the recorder's backfill), which
    retries."""
    import zenoh

    session = _SpySession()
    transport = ZenohTransport(session)
    transport.query_async("t/robot/2/collab", b"x", 0.25, lambda r: None, droppable=True)
    transport.query_async("t/sim/backfill", b"x", 0.25, lambda r: None)
    assert session.gets[0]["congestion_control"] == zenoh.CongestionControl.DROP
    assert "congestion_control" not in session.gets[1]


@pytest.mark.system
def test_zenoh_droppable_query_and_reply_round_trip(loopback_pair):
    """Dropping only happens on a congested link: on a healthy one a droppable query is answered."""
    a, b = loopback_pair
    b.serve("t/robot/2/collab", lambda p: b"ack " + p)
    for _ in range(50):  # the remote queryable may take a moment to propagate
        if a.query("t/robot/2/collab", b"probe", timeout=0.1):
            break
    finished = threading.Event()
    results: list[list[bytes]] = []
    a.query_async("t/robot/2/collab", b"help", 5.0,
                  lambda replies: (results.append(replies), finished.set()), droppable=True)
    assert finished.wait(5.0) and results == [[b"ack help"]]
