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
  robot at 5 Hz) is due beside the every-tick robots. ``summary(shared=…)`` splits the every-tick
  robots' latencies into those ticks and the others, which is where a fleet's tail comes from.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Iterable

import numpy as np

#: left edges [ms] of the latency histogram in ``sim_stats`` (the last bin is open-ended)
HISTOGRAM_EDGES_MS = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 7.5, 10.0,
                      15.0, 20.0, 50.0, 100.0)


class TimingStats:
    """Frame publication times, command latencies and deadline misses of one run."""

    def __init__(self, keep_frames: int = 1000):
        # (seq, offset [physics steps after the tick]) -> wall time [s] of publication
        self._published: OrderedDict[tuple[int, int], float] = OrderedDict()
        self._keep = keep_frames
        self._answered: dict[int, int] = {}  # robot -> newest seq answered
        self.robot_latencies: dict[int, list[float]] = {}  # robot -> its latencies [s]
        self.robot_seqs: dict[int, list[int]] = {}  # robot -> the seq of each latency
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
        if published is not None:
            self.robot_latencies.setdefault(robot, []).append(wall - published)
            self.robot_seqs.setdefault(robot, []).append(seq)

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

    def summary(self, every_tick: Iterable[int] = (),
                shared: Callable[[int], bool] | None = None) -> dict[str, object]:
        """Counts and latency percentiles [ms], over all commands and per robot (keys are robot
        ids as strings; NaN-free: absent when nothing was measured). With ``shared`` (seq → is a
        robot with divider ≥ 2 due) also ``latency_p{50,99}_ms_{shared,alone}``: the robots in
        ``every_tick``, on the shared ticks and on the others (module docstring)."""
        latencies = [v for values in self.robot_latencies.values() for v in values]
        out: dict[str, object] = {"commands": len(latencies), "due": self.expected,
                                  "missed": self.missed,
                                  "missed_by_robot": {str(robot): count for robot, count
                                                      in sorted(self.missed_by_robot.items())}}
        if latencies:
            ms = np.asarray(latencies) * 1000.0
            out.update(latency_p50_ms=float(np.percentile(ms, 50)),
                       latency_p99_ms=float(np.percentile(ms, 99)),
                       latency_max_ms=float(ms.max()))
            # per robot: a slow agent hides in the fleet's percentiles when it answers rarely
            # (an LTL agent at 5 Hz is 1 command in 60 beside 3 STL agents at 100 Hz)
            out["latency_p99_ms_by_robot"] = {
                str(robot): float(np.percentile(np.asarray(values) * 1000.0, 99))
                for robot, values in sorted(self.robot_latencies.items())}
            if shared is not None:
                out.update(self._split(set(every_tick), shared))
            counts, _ = np.histogram(ms, bins=(*HISTOGRAM_EDGES_MS, max(ms.max(), 1e3) + 1.0))
            out["latency_histogram_ms"] = {"edges": [*HISTOGRAM_EDGES_MS, "inf"],
                                           "counts": [int(c) for c in counts]}
        return out

    def _split(self, robots: set[int], shared: Callable[[int], bool]) -> dict[str, float]:
        groups: dict[str, list[float]] = {"shared": [], "alone": []}
        # ``shared`` once per tick, not once per (robot, tick): a 30-robot, 60 s run's summary
        # took 2 s of the simulator's exit
        group_of: dict[int, list[float]] = {}
        for robot in robots:
            for seq, value in zip(self.robot_seqs.get(robot, ()),
                                  self.robot_latencies.get(robot, ()), strict=True):
                group = group_of.get(seq)
                if group is None:
                    group = group_of[seq] = groups["shared" if shared(seq) else "alone"]
                group.append(value)
        out: dict[str, float] = {}
        for name, values in groups.items():
            if values:
                ms = np.asarray(values) * 1000.0
                out[f"latency_p50_ms_{name}"] = float(np.percentile(ms, 50))
                out[f"latency_p99_ms_{name}"] = float(np.percentile(ms, 99))
        return out
