"""The recorder's merge of frames by seq across gaps (issue 13:
tlfleet.coordinator.record.frame_merge), and the backfill through the recorder tap on the fake bus
(sim side: tlfleet.sim.frame_ring)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from tlfleet.agent.stl.monitor import read_trajectory_csv
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.bounds import FleetBounds
from tlfleet.bus.protocol.codec import ProtocolError, decode, encode
from tlfleet.bus.protocol.messages import BackfillReply, BackfillRequest, MocapFrame
from tlfleet.coordinator.record.frame_merge import MAX_REQUEST_FRAMES, FrameMerger, seq_ranges
from tlfleet.coordinator.record.recorder import Recorder, RecorderTap
from tlfleet.sim.frame_ring import FrameRing

RATE = 100.0  # [Hz]


def frame(seq: int) -> MocapFrame:
    t = seq / RATE
    return MocapFrame(t, seq, ((1, 0.1 * t, -0.2 * t, 0.0), (2, 1.0, t, 0.5)))


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class Merge:
    """A FrameMerger writing into lists, on a fake clock."""

    def __init__(self, **kwargs) -> None:
        self.clock = FakeClock()
        self.written: list[int] = []
        self.events: list[tuple[str, dict]] = []
        self.merger = FrameMerger(lambda f: self.written.append(f.seq),
                                  lambda kind, t, data: self.events.append((kind, data)),
                                  self.clock, **kwargs)

    def live(self, *seqs: int) -> None:
        for seq in seqs:
            self.merger.offer(frame(seq))

    def reply(self, first: int, last: int, seqs, oldest: int = 0) -> None:
        self.merger.backfill(first, last, oldest, [frame(s) for s in seqs])

    def kinds(self) -> list[str]:
        return [kind for kind, _ in self.events]


def test_without_a_gap_frames_go_out_in_order_the_newest_held_back():
    m = Merge()
    m.live(0, 0, 1, 2, 3)  # seq 0 twice: the later one wins, once
    assert m.written == [0, 1, 2] and m.merger.requests() == []
    m.merger.finish()
    assert m.written == [0, 1, 2, 3] and m.events == []
    assert m.merger.summary()["gaps"] == 0


def test_a_gap_holds_the_frames_after_it_until_the_backfill_fills_it():
    m = Merge()
    m.live(0, 1, 2, 8, 9, 10)  # 3..7 lost on a cut
    assert m.written == [0, 1, 2]  # 8, 9, 10 wait
    assert m.kinds() == ["trajectory_gap"]
    assert m.events[0][1] == {"first": 3, "last": 7, "frames": 5, "t_before": 0.02,
                              "t_after": 0.08}
    assert m.merger.requests() == [(3, 7)] and m.merger.waiting
    m.reply(3, 7, [7, 5, 3, 6, 4])  # out of order
    assert m.written == list(range(10))  # 10 is the newest: held back
    assert m.kinds() == ["trajectory_gap", "backfill"]
    done = m.events[1][1]
    assert (done["backfilled"], done["late"], done["unrecovered"], done["queries"]) == (5, 0, 0, 1)
    assert not m.merger.waiting


def test_overlapping_replies_and_late_live_frames_give_each_frame_once():
    m = Merge()
    m.live(0, 10)
    m.reply(1, 5, [1, 2, 3, 4, 5])
    m.reply(3, 7, [3, 4, 5, 6, 7])  # overlaps the first
    m.live(8)  # late on the live stream
    m.reply(8, 9, [8, 9, 9])  # 8 came live, 9 twice in one reply
    m.live(4, 11)  # a stale live frame, then the next one
    assert m.written == list(range(11))
    s = m.merger.summary()
    assert (s["backfilled"], s["late"], s["unrecovered"]) == (8, 1, 0)
    assert s["duplicates"] == 3 + 1 + 1 and s["stale"] == 1


def test_a_reply_covering_seqs_without_frames_makes_them_gone_and_named():
    m = Merge()
    m.live(0, 1, 20, 21)
    m.reply(2, 19, range(12, 20), oldest=12)  # the ring no longer has 2..11
    assert m.written == [0, 1, *range(12, 21)]  # written without waiting for 2..11
    (_, done) = m.events[-1]
    assert done["unrecovered"] == 10 and done["unrecovered_ranges"] == [[2, 11]]
    assert done["oldest_held"] == 12
    (r,) = m.merger.summary()["unrecovered_ranges"]
    assert (r["first"], r["last"], r["frames"]) == (2, 11, 10)
    assert r["t_first"] == pytest.approx(0.02) and r["t_last"] == pytest.approx(0.11)


def test_a_partial_reply_leaves_the_rest_to_ask_for_again_after_retry():
    m = Merge(retry=0.25)
    m.live(0, 100)
    assert m.merger.requests() == [(1, 99)]
    m.reply(1, 40, range(1, 41))  # budget-truncated: covers only 1..40
    assert m.written == list(range(41)) and m.merger.requests() == []  # not due yet
    m.clock.now = 0.3
    assert m.merger.requests() == [(41, 99)]
    m.reply(41, 99, range(41, 100))
    assert m.written == list(range(100))


def test_a_gap_that_waits_too_long_is_given_up_and_later_frames_are_dropped():
    m = Merge(wait=3.0)
    m.live(0, 5, 6)
    m.clock.now = 2.9
    m.merger.poll()
    assert m.written == [0]
    m.clock.now = 3.0
    m.merger.poll()
    assert m.written == [0, 5]
    m.reply(1, 4, [1, 2, 3, 4])  # too late: 1..4 were passed
    m.merger.finish()
    assert m.written == [0, 5, 6]
    s = m.merger.summary()
    assert s["unrecovered"] == 4 and s["duplicates"] == 4
    assert [(r["first"], r["last"]) for r in s["unrecovered_ranges"]] == [(1, 4)]


def test_holding_more_than_max_held_frames_gives_the_oldest_gap_up():
    m = Merge(max_held=5)
    m.live(0, 2, 3, 4, 5, 6, 7, 8)  # 1 missing; 7 frames held
    m.merger.poll()
    assert m.written == [0, *range(2, 8)]  # 8, the newest, held back
    assert m.merger.summary()["unrecovered"] == 1


def test_one_poll_gives_up_as_many_gaps_as_the_bound_needs():
    """Three gaps hold 8 frames: with max_held = 2 one poll gives up every gap it must (giving
    one up closes it: the poll does not walk the list it shrinks)."""
    m = Merge(max_held=2)
    m.live(0, 2, 3, 5, 6, 8, 9, 10)  # 1, 4 and 7 missing
    m.merger.poll()
    assert len(m.merger.held) <= 2
    assert m.written == [0, 2, 3, 5, 6, 8, 9]  # 10, the newest, held back
    assert m.merger.summary()["unrecovered"] == 3


def test_the_end_of_the_run_gives_every_gap_up_and_writes_everything_held():
    m = Merge()
    m.live(0, 3, 4, 9)
    m.merger.finish()
    assert m.written == [0, 3, 4, 9]
    assert [d["unrecovered_ranges"] for k, d in m.events if k == "backfill"] == [[[1, 2]],
                                                                              [[5, 8]]]


def test_requests_per_gap_are_bounded_and_frames_outside_a_reply_ignored():
    m = Merge()
    m.live(0, 3, 5000)
    assert m.merger.requests() == [(1, 2), (4, 4 + MAX_REQUEST_FRAMES - 1)]
    m.reply(1, 2, [1, 2, 4])  # 4 is not in what this reply covers
    assert m.merger.summary()["ignored"] == 1 and m.written == [0, 1, 2, 3]


def test_seq_ranges():
    assert seq_ranges([]) == [] and seq_ranges([4]) == [(4, 4)]
    assert seq_ranges([1, 2, 3, 7, 9, 10]) == [(1, 3), (7, 7), (9, 10)]


def test_a_bad_merger_setting_is_rejected():
    with pytest.raises(ValueError, match="wait = 0"):
        FrameMerger(print, print, FakeClock(), wait=0)


# ------------------------------------------------------------------ through the tap, fake bus


class Fleet:
    """A recorder and its tap, a 'simulator' with a FrameRing serving ``sim/backfill``, and a
    live stream whose frames a test can drop (a cut)."""

    def __init__(self, tmp_path, *, ring_frames: int = 1000, serve: bool = True) -> None:
        self.net = FakeNetwork()
        self.clock = FakeClock()
        self.sim = self.net.transport("sim")
        self.ring = FrameRing(ring_frames)
        if serve:
            self.sim.serve(keys.sim_backfill("f"), self._answer)
        self.recorder = Recorder(tmp_path, [1, 2], clock=self.clock, backfill_wait=3.0)
        bounds = FleetBounds((-5.0, 5.0, -5.0, 5.0), 100.0, RATE)
        self.tap = RecorderTap(self.net.transport("coordinator"), "f", self.recorder,
                               bounds=bounds, max_jump=100)
        self.recorder.start()
        self.dir = tmp_path

    def _answer(self, payload: bytes) -> bytes | None:
        try:
            return encode(self.ring.answer(decode(BackfillRequest, payload)))
        except ProtocolError:
            return None

    def publish(self, seqs, cut=()) -> None:
        for seq in seqs:
            data = encode(frame(seq))
            self.ring.append(seq, data)
            if seq not in cut:
                self.sim.publish(keys.mocap("f"), data)
            self.tap.drain()

    def close(self):
        self.tap.close()
        self.recorder.close()
        return read_trajectory_csv(self.dir / "trajectory.csv")

    def events(self, kind):
        lines = (self.dir / "events.jsonl").read_text().splitlines()
        return [e for e in map(json.loads, lines) if e["kind"] == kind]


def test_a_cut_longer_than_the_gate_is_backfilled_through_the_tap(tmp_path):
    fleet = Fleet(tmp_path)
    fleet.publish(range(600), cut=range(100, 350))  # 2.5 s lost; 350 is held by the gate
    traj = fleet.close()
    np.testing.assert_allclose(traj.t, np.arange(600) / RATE)
    (gap,), (done,) = fleet.events("trajectory_gap"), fleet.events("backfill")
    assert (gap["data"]["first"], gap["data"]["last"]) == (100, 350)
    assert done["data"]["backfilled"] == 251 and done["data"]["unrecovered"] == 0
    assert fleet.tap.malformed["mocap"] == 1  # the gate held the first frame after the jump
    assert fleet.recorder.backfill_summary()["unrecovered"] == 0


def test_frames_older_than_the_ring_are_named_as_an_unrecoverable_gap(tmp_path):
    fleet = Fleet(tmp_path, ring_frames=100)
    # the gap shows at seq 351 (350 held by the gate), when the ring holds 252..351
    fleet.publish(range(400), cut=range(100, 350))
    traj = fleet.close()
    seqs = np.rint(traj.t * RATE).astype(int)
    assert seqs.tolist() == [*range(100), *range(252, 400)]
    (r,) = fleet.recorder.backfill_summary()["unrecovered_ranges"]
    assert (r["first"], r["last"], r["frames"], r["oldest_held"]) == (100, 251, 152, 252)
    assert fleet.events("backfill")[0]["data"]["unrecovered_ranges"] == [[100, 251]]


def test_malformed_replies_and_implausible_frames_are_counted_never_recorded(tmp_path):
    fleet = Fleet(tmp_path, serve=False)
    rogue = fleet.net.transport("rogue")
    bad_frame = encode(MocapFrame(0.5, 50, ((1, 999.0, 0.0, 0.0), (2, 0.0, 0.0, 0.0))))
    answers = iter([b"\xc1 junk", encode(BackfillReply(0, 9, 0, (b"\xc1",))),
                    encode(BackfillReply(50, 50, 0, (bad_frame,)))])
    rogue.serve(keys.sim_backfill("f"), lambda payload: next(answers, None))
    fleet.publish(range(50))
    fleet.publish(range(60, 70))
    fleet.clock.now = 0.3
    fleet.publish([70])
    fleet.clock.now = 0.6
    fleet.publish([71])
    assert fleet.tap.malformed["backfill"] == 3
    fleet.clock.now = 3.5  # the gap waited its 3 s: given up
    fleet.publish([72])
    traj = fleet.close()
    seqs = np.rint(traj.t * RATE).astype(int)
    assert seqs.tolist() == [*range(50), *range(60, 73)]  # 999 m never made it in
    assert fleet.recorder.backfill_summary()["unrecovered"] == 10


def test_a_gap_open_when_the_run_ends_gets_one_last_blocking_attempt(tmp_path):
    fleet = Fleet(tmp_path)
    fleet.publish(range(30))
    fleet.tap._ask_backfill = lambda force=False: None  # (no query while the run goes)
    fleet.publish(range(30, 40), cut=range(30, 35))
    assert fleet.recorder.backfill_waiting
    del fleet.tap._ask_backfill
    traj = fleet.close()
    np.testing.assert_allclose(traj.t, np.arange(40) / RATE)
