"""The simulator's ring of recent frames (tlfleet.sim.frame_ring) and its ``sim/backfill``
queryable, on the fake bus."""

from __future__ import annotations

import threading

import pytest
from sim_helpers import FLEET, FakeAgent, Observer, SimRun, omni, scenario
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import ProtocolError, decode, encode
from tlfleet.bus.protocol.messages import BackfillReply, BackfillRequest, MocapFrame
from tlfleet.sim.frame_ring import FrameRing, ring_size
from tlfleet.sim.process import SimConfig, SimConfigError


def payload(seq: int, size: int = 10) -> bytes:
    return bytes([seq % 256]) * size


def filled(seqs, max_frames=100, max_bytes=10_000, size=10) -> FrameRing:
    ring = FrameRing(max_frames, max_bytes)
    for seq in seqs:
        ring.append(seq, payload(seq, size))
    return ring


def held(ring: FrameRing) -> list[int]:
    reply = ring.answer(BackfillRequest(0, 10 ** 9))
    return [f[0] for f in reply.frames]  # payload(seq)[0] = seq % 256


def test_the_frame_bound_evicts_the_oldest_first():
    ring = filled(range(25), max_frames=10)
    assert len(ring) == 10 and ring.oldest == 15 and ring.evicted == 15
    assert held(ring) == list(range(15, 25))
    assert ring.bytes == 100


def test_the_byte_bound_evicts_too_and_keeps_at_least_the_newest():
    ring = filled(range(20), max_frames=1000, max_bytes=55)  # 10 bytes each: 5 fit
    assert held(ring) == [15, 16, 17, 18, 19] and ring.bytes == 50
    ring.append(20, b"x" * 500)  # larger than the whole bound: kept alone
    assert len(ring) == 1 and ring.oldest == 20 and ring.bytes == 500
    ring.append(21, payload(21))  # and evicted by the next one
    assert len(ring) == 1 and ring.oldest == 21 and ring.evicted == 15 + 5 + 1


def test_seqs_must_increase():
    ring = filled([3, 4])
    for seq in (4, 2):
        with pytest.raises(ValueError, match=f"seq {seq} does not follow 4"):
            ring.append(seq, b"x")
    assert held(ring) == [3, 4]


def test_an_answer_holds_the_requested_range_in_order_and_covers_it():
    ring = filled(range(10, 30))
    reply = ring.answer(BackfillRequest(12, 15))
    assert (reply.first, reply.last, reply.oldest) == (12, 15, 10)
    assert reply.frames == tuple(payload(s) for s in (12, 13, 14, 15))
    # partly older than the ring: covered, without the evicted frames
    reply = ring.answer(BackfillRequest(5, 11))
    assert (reply.first, reply.last, reply.oldest) == (5, 11, 10)
    assert reply.frames == (payload(10), payload(11))
    # wholly older, or beyond the newest: covered and empty
    assert ring.answer(BackfillRequest(0, 9)).frames == ()
    assert ring.answer(BackfillRequest(40, 50)) == BackfillReply(40, 50, 10, ())
    assert FrameRing(5).answer(BackfillRequest(0, 3)) == BackfillReply(0, 3, -1, ())
    assert ring.queries == 4 and ring.frames_sent == 6


def test_an_answer_stops_at_its_budget_and_covers_only_what_it_carries():
    ring = filled(range(100), size=10)
    reply = ring.answer(BackfillRequest(20, 80), max_bytes=95)  # 9 frames fit
    assert reply.first == 20 and reply.last == 28 and len(reply.frames) == 9
    reply = ring.answer(BackfillRequest(20, 80), max_frames=4)
    assert reply.last == 23 and len(reply.frames) == 4
    big = filled(range(3), size=50)
    reply = big.answer(BackfillRequest(0, 2), max_bytes=10)  # one frame even over the budget
    assert reply.last == 0 and reply.frames == (payload(0, 50),)
    # the ring's own answers always decode (bounds: frames ≤ seqs covered)
    assert decode(BackfillReply, encode(ring.answer(BackfillRequest(0, 99)))).last == 99


def test_the_ring_is_safe_to_answer_while_the_loop_appends():
    ring = FrameRing(50)
    errors: list[BaseException] = []

    def ask() -> None:
        try:
            for _ in range(2000):
                frames = ring.answer(BackfillRequest(0, 10 ** 6)).frames
                seqs = [int.from_bytes(f, "big") for f in frames]
                assert seqs == sorted(seqs) and len(seqs) <= 50
        except BaseException as exc:  # reported by the main thread
            errors.append(exc)

    asker = threading.Thread(target=ask)
    asker.start()
    for seq in range(20_000):
        ring.append(seq, seq.to_bytes(4, "big"))
    asker.join(10.0)
    assert not asker.is_alive() and errors == []


@pytest.mark.parametrize(("seconds", "rate", "frames"), [
    (10.0, 100.0, 1000), (2.5, 100.0, 250), (0.0, 100.0, 1), (0.015, 100.0, 2), (1.0, 30.0, 30)])
def test_ring_size_in_frames(seconds, rate, frames):
    assert ring_size(seconds, rate) == frames


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_bad_ring_settings_are_rejected(bad):
    with pytest.raises(ValueError, match="backfill_seconds"):
        ring_size(bad, 100.0)
    with pytest.raises(SimConfigError, match="backfill_seconds"):
        SimConfig(backfill_seconds=bad)
    with pytest.raises(ValueError, match="bounds must be ≥ 1"):
        FrameRing(0)


def test_the_sim_serves_its_published_frames_and_survives_bad_requests():
    """Realtime on the fake bus: ``sim/backfill`` answers with the very payloads published on
    ``mocap``; a request that does not decode gets no reply and counts as malformed."""
    net = FakeNetwork()
    observer = Observer(net)
    FakeAgent(net, 1, lambda frame, robot: (0.0, 0.0, 0.0), realtime_divider=1)
    asker = net.transport("recorder")
    key = keys.sim_backfill(FLEET)
    with SimRun(net, scenario(omni(1, 0.0, 0.0), duration=1.0), mode="realtime",
                backfill_seconds=0.2) as run:
        observer.start_mission()
        assert observer.wait_for(lambda: observer.frames[-1].seq >= 40)
        assert asker.query(key, b"\xc1 junk", 1.0) == []
        assert asker.query(key, encode(BackfillRequest(9, 3)), 1.0) == []  # last < first
        (raw,) = asker.query(key, encode(BackfillRequest(0, 30)), 1.0)
        assert run.join() == 0
    reply = decode(BackfillReply, raw)
    published = {f.seq: b for f, b in zip(observer.frames, observer.frame_bytes, strict=True)}
    assert reply.first == 0 and reply.last == 30 and reply.oldest > 0  # 0.2 s = 20 frames kept
    seqs = [decode(MocapFrame, f).seq for f in reply.frames]
    assert seqs == list(range(reply.oldest, 31)) and len(seqs) <= 20
    assert all(published[s] == f for s, f in zip(seqs, reply.frames, strict=True))
    assert run.process.malformed[key] == 2
    stats = run.process.summary()["backfill"]
    assert stats["max_frames"] == 20 and stats["queries"] == 1 and stats["evicted"] > 0
    with pytest.raises(ProtocolError):
        decode(BackfillRequest, b"\xc1 junk")
