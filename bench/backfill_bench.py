"""What the backfill costs on the hot path, per frame, in-process (no fleet):

    .venv/bin/python bench/backfill_bench.py [--quick] [--out FILE.json]

* ``ring_append_us``: the simulator's ``FrameRing.append`` of one published payload (Scenario 1
  frames: 5 robots, ≈ 190 bytes), beside ``encode_us``, the frame's encoding that every tick
  pays anyway (``SimProcess._publish_frame``);
* ``merge_offer_us``: the recorder's ``FrameMerger.offer`` of one frame in order (no gap: what
  every run without faults pays), file writing excluded;
* ``backfill_answer_ms``: one ``FrameRing.answer`` of 1000 frames (a 10 s ring, the whole of
  it) encoded as a ``BackfillReply``, and ``backfill_merge_ms``: merging those 1000 frames after
  a gap (decoding included): what a cut costs, once.

CPU of this thread (``time.thread_time``) beside wall, medians of ≥ 3 runs (bench/common.py).
Informative: no targets. At 100 Hz a per-frame cost of x µs is x/10 ms of CPU per sim second,
to compare with the simulator's ≈ 110–140 ms per sim second (measured with psutil, README).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tlfleet.bus.protocol.codec import decode, encode  # noqa: E402
from tlfleet.bus.protocol.messages import BackfillReply, BackfillRequest, MocapFrame  # noqa: E402
from tlfleet.coordinator.record.frame_merge import FrameMerger  # noqa: E402
from tlfleet.sim.frame_ring import FrameRing  # noqa: E402

from bench.common import RESULTS, Figure, load_average, report, time_calls  # noqa: E402


def frames_of(n: int, robots: int = 5) -> list[MocapFrame]:
    return [MocapFrame(k / 100, k, tuple((r, 0.1 * r + 1e-4 * k, -0.3, 0.2)
                                         for r in range(1, robots + 1))) for k in range(n)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", type=Path, default=RESULTS / "backfill_bench.json")
    args = parser.parse_args(argv)
    load_before = load_average()
    n = 20_000 if args.quick else 100_000
    runs = 3 if args.quick else 5
    frames = frames_of(n)
    payloads = [encode(f) for f in frames]
    figures = []

    def appends() -> None:
        ring = FrameRing(1000)
        for k, payload in enumerate(payloads):
            ring.append(k, payload)

    def encodes() -> None:
        for frame in frames:
            encode(frame)

    def offers() -> None:
        merger = FrameMerger(lambda f: None, lambda *a: None, time.monotonic)
        for frame in frames:
            merger.offer(frame)

    for key, label, fn in (("ring_append_us", "sim: FrameRing.append, per frame", appends),
                           ("encode_us", "sim: encode(frame), per frame (paid anyway)", encodes),
                           ("merge_offer_us", "recorder: FrameMerger.offer in order, per frame",
                            offers)):
        t = time_calls(fn, runs)
        figures.append(Figure(key, label, t.cpu / n * 1e6, "µs", wall=t.wall / n * 1e6))

    ring = FrameRing(1000)
    for k, payload in enumerate(payloads[:2000]):
        ring.append(k, payload)
    request = BackfillRequest(1000, 1999)
    t = time_calls(lambda: encode(ring.answer(request)), runs * 4)
    figures.append(Figure("backfill_answer_ms", "sim: answer + encode 1000 frames (once a cut)",
                          t.cpu * 1e3, "ms", wall=t.wall * 1e3))
    raw = encode(ring.answer(request))

    def merge_gap() -> None:
        merger = FrameMerger(lambda f: None, lambda *a: None, time.monotonic)
        merger.offer(frames[999])
        merger.offer(frames[2000])
        reply = decode(BackfillReply, raw)
        merger.backfill(reply.first, reply.last, reply.oldest,
                        [decode(MocapFrame, p) for p in reply.frames])
        assert merger.cursor == 2000, "the gap was not filled"

    t = time_calls(merge_gap, runs * 4)
    figures.append(Figure("backfill_merge_ms", "recorder: decode + merge 1000 frames (once a cut)",
                          t.cpu * 1e3, "ms", wall=t.wall * 1e3))
    report("backfill_bench", figures, args.out, load_before=load_before, quick=args.quick,
           extra={"frame_bytes": len(payloads[0]), "frames_per_run": n})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
