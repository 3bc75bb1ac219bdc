"""Command timing as the simulator sees it (latency and missed control deadlines).

* **Latency** of a command: its arrival at the sim (wall clock, taken in the transport callback)
  minus the publication of the frame it answers (same ``seq``, and for an answer to a frame
  sampled after its tick, ``SimParams.spread_frames``, the same offset) [s]. Both are read on
  the sim's own monotonic clock, so no clock synchronisation is involved.
* **Control deadline** of robot r at tick k (r due at k): its ``Command(seq=k)`` must have
  arrived before the sim steps the physics from t_k to t_{k+1} (with spread frames, past
  t_{k+1} + s_r·dt: one period after r's frame; the simulator closes it then). In lockstep the
  sim waits (up to the tick timeout), so only timeouts miss; in realtime the step happens one
  mocap period after the frame, whatever arrived, and tick 0 owes nothing (agents cannot tell
  its frame from the preview frame, which they never answer).
* **Shared ticks**: the ticks on which a robot with a control divider ≥ 2 (an LTL
  robot at 5 Hz) is due beside the every-tick robots. ``TimingStats(shared=…)`` splits the
  every-tick robots' latencies into those ticks and the others, which is where a fleet's tail
  comes from.
* **Constant memory**: latencies go into :class:`LatencySketch` es (exact up to 4 096 values a
  robot, then a histogram with 1 % bins), frames and answers of recent ticks only.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable, Iterable

import numpy as np

#: left edges [ms] of the latency histogram in ``sim_stats`` (the last bin is open-ended)
HISTOGRAM_EDGES_MS = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 7.5, 10.0,
                      15.0, 20.0, 50.0, 100.0)


class LatencySketch:
    """Latencies [s] in constant memory: the values themselves while there are at most
    ``exact`` of them (percentiles then as ``numpy.percentile`` gives them), afterwards a
    histogram of geometric bins of relative width :data:`RATIO` - 1 between :data:`LOWEST` and
    :data:`HIGHEST` (a percentile then within 0.5 % of the exact one; the maximum stays exact).
    A simulator keeps one per robot for the whole run: a list of every latency grew by about
    65 MB an hour in a realtime soak."""

    __slots__ = ("_bins", "_exact", "_values", "count", "max", "min")

    def __init__(self, exact: int = 4096):
        self._exact = exact
        self._values: list[float] | None = []
        self._bins: np.ndarray | None = None
        self.count = 0
        self.max = -math.inf
        self.min = math.inf

    def __len__(self) -> int:
        return self.count

    def values(self) -> list[float]:
        """The values, while they are kept (at most ``exact``); ValueError after."""
        if self._values is None:
            raise ValueError(f"a sketch of {self.count} values keeps a histogram only")
        return list(self._values)

    def add(self, value: float) -> None:
        self.count += 1
        if value > self.max:
            self.max = value
        if value < self.min:
            self.min = value
        if self._values is not None:
            self._values.append(value)
            if len(self._values) > self._exact:
                self._fold()
        else:
            self._bins[_bin(value)] += 1

    def _fold(self) -> None:
        self._bins = np.zeros(BINS, dtype=np.int64)
        for value in self._values:
            self._bins[_bin(value)] += 1
        self._values = None

    def merge(self, other: LatencySketch) -> None:
        """Add every value of ``other`` (its histogram, once it has one)."""
        if other._values is not None:
            for value in other._values:
                self.add(value)
            return
        if self._values is not None:
            self._fold()
        self._bins += other._bins
        self.count += other.count
        self.max = max(self.max, other.max)
        self.min = min(self.min, other.min)

    def percentile(self, q: float) -> float:
        """The q-th percentile (0 ≤ q ≤ 100) [s]; NaN when empty."""
        if not self.count:
            return math.nan
        if self._values is not None:
            return float(np.percentile(self._values, q))
        rank = q / 100.0 * (self.count - 1)  # numpy's linear rule, on the bins' midpoints
        cumulative = np.cumsum(self._bins)
        index = int(np.searchsorted(cumulative, rank + 1.0))
        return max(min(_midpoint(index), self.max), self.min)

    def histogram(self, edges_ms: tuple[float, ...]) -> list[int]:
        """Counts of the latencies [ms] between consecutive ``edges_ms`` (the last bin open)."""
        top = max(self.max * 1000.0, 1e3) + 1.0
        bounds = (*edges_ms, top)
        if self._values is not None:
            counts, _ = np.histogram(np.asarray(self._values) * 1000.0, bins=bounds)
            return [int(c) for c in counts]
        mids = np.array([_midpoint(i) for i in range(BINS)]) * 1000.0
        counts, _ = np.histogram(mids, bins=bounds, weights=self._bins)
        return [int(c) for c in counts]


RATIO = 1.01  # geometric bin width of a folded sketch: a percentile within 0.5 %
LOWEST = 1e-6  # [s] the first bin's lower edge (everything below counts in bin 0)
HIGHEST = 100.0  # [s] the last bin's lower edge (everything above counts in the last bin)
BINS = math.ceil(math.log(HIGHEST / LOWEST) / math.log(RATIO)) + 1
_LOG_RATIO = math.log(RATIO)


def _bin(value: float) -> int:
    if not value > LOWEST:
        return 0
    return min(BINS - 1, int(math.log(value / LOWEST) / _LOG_RATIO))


def _midpoint(index: int) -> float:
    """The geometric middle of bin ``index`` [s]."""
    return LOWEST * RATIO ** (index + 0.5)


class TimingStats:
    """Frame publication times, command latencies and deadline misses of one run, in memory
    that does not grow with the run's length (:class:`LatencySketch`).

    ``shared`` (seq → a robot with control divider ≥ 2 is due) and ``every_tick`` (the robots
    due every tick) split those robots' latencies into the shared ticks and the others as they
    arrive (module docstring)."""

    def __init__(self, keep_frames: int = 1000, *, shared: Callable[[int], bool] | None = None,
                 every_tick: Iterable[int] = ()):
        # (seq, offset [physics steps after the tick]) -> wall time [s] of publication
        self._published: OrderedDict[tuple[int, int], float] = OrderedDict()
        self._keep = keep_frames
        self._answered: dict[int, int] = {}  # robot -> newest seq answered
        self.robot_latencies: dict[int, LatencySketch] = {}  # robot -> its latencies [s]
        self._shared = shared
        self._every_tick = frozenset(every_tick)
        self._split: dict[str, LatencySketch] = {"shared": LatencySketch(),
                                                 "alone": LatencySketch()}
        self._shared_of: OrderedDict[int, bool] = OrderedDict()  # seq -> shared (recent ticks)
        self.expected = 0  # due (robot, tick) pairs
        self.missed = 0
        self.missed_by_robot: dict[int, int] = {}

    def frame_published(self, seq: int, wall: float, *, offset: int = 0) -> None:
        """Frame ``seq`` (sampled ``offset`` physics steps after its tick) went out at ``wall``
        [s]. The frames of the last ``keep_frames`` ticks are remembered."""
        published = self._published
        published[(seq, offset)] = wall
        while next(iter(published))[0] <= seq - self._keep:
            published.popitem(last=False)

    def command_arrived(self, robot: int, seq: int, wall: float, *, offset: int = 0) -> None:
        """Record a command accepted for ``seq`` (answering the frame sampled ``offset`` physics
        steps after that tick); its latency if that frame is remembered."""
        self.answered(robot, seq)
        published = self._published.get((seq, offset))
        if published is None:
            return
        latency = wall - published
        sketch = self.robot_latencies.get(robot)
        if sketch is None:
            sketch = self.robot_latencies[robot] = LatencySketch()
        sketch.add(latency)
        if self._shared is not None and robot in self._every_tick:
            self._split["shared" if self._shared_tick(seq) else "alone"].add(latency)

    def _shared_tick(self, seq: int) -> bool:
        """``shared(seq)`` once per tick, not once per (robot, tick): at fleet scale it is not
        free; the answers of the recent ticks are kept."""
        found = self._shared_of.get(seq)
        if found is None:
            found = self._shared_of[seq] = bool(self._shared(seq))
            while len(self._shared_of) > self._keep:
                self._shared_of.popitem(last=False)
        return found

    def answered(self, robot: int, seq: int) -> None:
        """Record an answer whose latency is not measurable (an early answer to tick 0)."""
        self._answered[robot] = max(seq, self._answered.get(robot, -1))

    def close_tick(self, seq: int, due: Iterable[int]) -> tuple[int, ...]:
        """The sim steps past tick ``seq``: count the due robots whose command is missing."""
        due = tuple(due)
        late = tuple(r for r in due if self._answered.get(r, -1) < seq)
        self.expected += len(due)
        self.missed += len(late)
        for robot in late:
            self.missed_by_robot[robot] = self.missed_by_robot.get(robot, 0) + 1
        return late

    def summary(self) -> dict[str, object]:
        """Counts and latency percentiles [ms], over all commands and per robot (keys are robot
        ids as strings; NaN-free: absent when nothing was measured); with ``shared`` also
        ``latency_p{50,99}_ms_{shared,alone}``: the every-tick robots on the shared ticks and
        on the others."""
        every = LatencySketch()
        for sketch in self.robot_latencies.values():
            every.merge(sketch)
        out: dict[str, object] = {"commands": every.count, "due": self.expected,
                                  "missed": self.missed,
                                  "missed_by_robot": {str(robot): count for robot, count
                                                      in sorted(self.missed_by_robot.items())}}
        if every.count:
            out.update(latency_p50_ms=1000.0 * every.percentile(50),
                       latency_p99_ms=1000.0 * every.percentile(99),
                       latency_max_ms=1000.0 * every.max)
            # per robot: a slow agent hides in the fleet's percentiles when it answers rarely
            # (an LTL agent at 5 Hz is 1 command in 60 beside 3 STL agents at 100 Hz)
            out["latency_p99_ms_by_robot"] = {
                str(robot): 1000.0 * sketch.percentile(99)
                for robot, sketch in sorted(self.robot_latencies.items())}
            for name, sketch in self._split.items():
                if sketch.count:
                    out[f"latency_p50_ms_{name}"] = 1000.0 * sketch.percentile(50)
                    out[f"latency_p99_ms_{name}"] = 1000.0 * sketch.percentile(99)
            out["latency_histogram_ms"] = {"edges": [*HISTOGRAM_EDGES_MS, "inf"],
                                           "counts": every.histogram(HISTOGRAM_EDGES_MS)}
        return out
