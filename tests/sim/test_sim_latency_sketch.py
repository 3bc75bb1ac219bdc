"""The simulator's latency statistics in constant memory (``tlfleet.sim.stats.LatencySketch``):
exact while small, then a histogram whose percentiles stay within 0.5 % of numpy's on the same
values, checked on skewed random latencies; a run's length no longer grows the simulator."""

from __future__ import annotations

import numpy as np
import pytest
from tlfleet.sim.stats import BINS, HISTOGRAM_EDGES_MS, LatencySketch, TimingStats


def lognormal(n: int, seed: int) -> np.ndarray:
    """Latencies [s] shaped like a loaded machine's: a median near 1 ms, a long tail."""
    return np.random.default_rng(seed).lognormal(mean=np.log(1e-3), sigma=0.8, size=n)


def test_small_sketches_are_exact():
    values = lognormal(1000, 1)
    sketch = LatencySketch()
    for v in values:
        sketch.add(float(v))
    for q in (0, 50, 99, 100):
        assert sketch.percentile(q) == pytest.approx(np.percentile(values, q), rel=1e-12)
    assert sketch.values() == pytest.approx(list(values))
    assert (sketch.min, sketch.max, len(sketch)) == (values.min(), values.max(), 1000)


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_large_sketches_stay_within_half_a_percent(seed):
    values = lognormal(200_000, seed)
    sketch = LatencySketch(exact=1000)
    for v in values:
        sketch.add(float(v))
    with pytest.raises(ValueError):
        sketch.values()  # only the histogram is kept
    for q in (1, 50, 90, 99, 99.9):
        assert sketch.percentile(q) == pytest.approx(np.percentile(values, q), rel=5e-3), q
    assert sketch.max == values.max() and sketch.min == values.min()
    counts = sketch.histogram(HISTOGRAM_EDGES_MS)
    exact, _ = np.histogram(values * 1e3, bins=(*HISTOGRAM_EDGES_MS, 1e3 + 1))
    assert sum(counts) == len(values)
    # a value within 1 % of an edge may land in the next bin (each such value counts twice in
    # the sum of differences): the 1 ms edge sits at this distribution's median, ~1.5 % move
    assert sum(abs(a - b) for a, b in zip(counts, exact, strict=True)) < 0.04 * len(values)


def test_merging_sketches_is_adding_their_values():
    a, b = lognormal(3000, 5), lognormal(5000, 6)
    left, right = LatencySketch(exact=2000), LatencySketch(exact=2000)
    for v in a:
        left.add(float(v))
    for v in b:
        right.add(float(v))
    both = LatencySketch(exact=2000)
    both.merge(left)
    both.merge(right)
    union = np.concatenate([a, b])
    assert len(both) == len(union) and both.max == union.max()
    assert both.percentile(99) == pytest.approx(np.percentile(union, 99), rel=5e-3)


def test_the_timing_stats_of_a_long_run_hold_no_list_of_latencies():
    stats = TimingStats(every_tick=[1, 2], shared=lambda seq: seq % 20 == 0)
    values = lognormal(3 * 20_000, 7)
    for seq in range(20_000):
        stats.frame_published(seq, float(seq))
        for robot in (1, 2, 3):
            stats.command_arrived(robot, seq, seq + float(values[3 * seq + robot - 1]))
    for sketch in stats.robot_latencies.values():
        with pytest.raises(ValueError):
            sketch.values()
        assert sketch._bins.shape == (BINS,)  # the whole state of a folded sketch
    summary = stats.summary()
    assert summary["commands"] == 60_000
    assert summary["latency_p99_ms"] == pytest.approx(1e3 * np.percentile(values, 99), rel=5e-3)
    assert summary["latency_max_ms"] == pytest.approx(1e3 * values.max())
