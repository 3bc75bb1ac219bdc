"""What every tlfleet benchmark shares (issue 17 item 6): CPU beside wall, load, targets, JSON.

The benchmark machine is shared (2 cores, several engineers): wall-clock figures carry whatever
else runs, so every timed figure is measured as **CPU time of the measuring thread**
(``time.thread_time``) beside wall time (``time.perf_counter``), both as medians over runs, and
every table and JSON file carries the load average before and after. Targets are compared with
the CPU figure where there is one (what the code costs), and a figure without a target is
informative only.

    figures = [Figure("step_us", "control step", cpu, "µs", target=50.0, wall=wall)]
    report("stl_bench", figures, out_path, extra={...})   # prints the table, writes the JSON
"""

from __future__ import annotations

import json
import math
import os
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Literal

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"


def load_average() -> tuple[float, float, float]:
    """1, 5 and 15 min load averages of the machine (NaN where unavailable)."""
    try:
        return os.getloadavg()
    except OSError:
        return (math.nan, math.nan, math.nan)


def sorted_quantile(values: Sequence[float], q: float) -> float:
    """The q-quantile (0 ≤ q < 1) of ``values`` sorted ascending, as the nearest lower rank
    (NaN when empty): the benchmarks' latency p50 and p99."""
    if not values:
        return math.nan
    return values[min(len(values) - 1, int(q * len(values)))]


@dataclass(frozen=True)
class Timing:
    """Median CPU and wall time per call [s] over ``runs`` runs of ``calls`` calls, and spreads."""

    cpu: float
    wall: float
    cpu_runs: tuple[float, ...]
    wall_runs: tuple[float, ...]
    calls: int


def time_calls(fn: Callable[[], object], runs: int, calls: int = 1,
               setup: Callable[[], object] | None = None) -> Timing:
    """Median per-call CPU (this thread) and wall time of ``fn()``; ``setup()`` runs untimed
    before each run. At least 3 runs."""
    cpu_runs, wall_runs = [], []
    for _ in range(max(3, runs)):
        if setup is not None:
            setup()
        c0, w0 = time.thread_time(), time.perf_counter()
        for _ in range(calls):
            fn()
        c1, w1 = time.thread_time(), time.perf_counter()
        cpu_runs.append((c1 - c0) / calls)
        wall_runs.append((w1 - w0) / calls)
    return Timing(statistics.median(cpu_runs), statistics.median(wall_runs), tuple(cpu_runs),
                  tuple(wall_runs), calls)


@dataclass(frozen=True)
class Figure:
    """One benchmark figure. ``value`` is what the target is checked on (CPU for timings);
    ``wall`` the wall-clock counterpart, when there is one. ``better``: the direction of
    the target (``value <= target`` or ``value >= target``)."""

    key: str
    label: str
    value: float
    unit: str
    target: float | None = None
    better: Literal["lower", "higher"] = "lower"
    wall: float | None = None
    note: str = ""

    @property
    def met(self) -> bool | None:
        if self.target is None:
            return None
        if not math.isfinite(self.value):
            return False
        return self.value <= self.target if self.better == "lower" else self.value >= self.target

    def target_text(self) -> str:
        if self.target is None:
            return "-"
        return f"{'≤' if self.better == 'lower' else '≥'} {self.target:g} {self.unit}"


def _fmt(value: float | None, unit: str) -> str:
    if value is None:
        return "-"
    if not math.isfinite(value):
        return "n/a"
    digits = 3 if abs(value) < 10 else 1 if abs(value) < 1000 else 0
    return f"{value:.{digits}f} {unit}"


def print_table(title: str, figures: Sequence[Figure], load_before: Sequence[float],
                load_after: Sequence[float]) -> None:
    print(f"{title} (python {platform.python_version()}, {os.cpu_count()} cores; load average "
          f"{load_before[0]:.2f} before, {load_after[0]:.2f} after)")
    print(f"{'measure':<58} {'value (CPU)':>14} {'wall':>14} {'target':>14}  met")
    for f in figures:
        met = "" if f.met is None else "met" if f.met else "NOT MET"
        print(f"{f.label:<58} {_fmt(f.value, f.unit):>14} {_fmt(f.wall, f.unit):>14} "
              f"{f.target_text():>14}  {met}")
        if f.note:
            print(f"    {f.note}")


def figure_records(figures: Sequence[Figure]) -> list[dict]:
    """``figures`` as the JSON rows ``bench/summary.py`` reads (each with its ``met``)."""
    return [{**asdict(f), "met": f.met} for f in figures]


def report(name: str, figures: Sequence[Figure], out: Path, *, load_before: Sequence[float],
           extra: dict | None = None, quick: bool = False) -> dict:
    """Print the table and write ``out`` (JSON): figures with targets and met, load, machine."""
    load_after = load_average()
    print_table(f"{name} ({'quick' if quick else 'full'})", figures, load_before, load_after)
    payload = {
        "benchmark": name,
        "quick": quick,
        "time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "load_average_before": list(load_before),
        "load_average_after": list(load_after),
        "figures": figure_records(figures),
        "results": {f.key: f.value for f in figures},
        "targets": {f.key: f.target for f in figures if f.target is not None},
        "meets_targets": {f.key: f.met for f in figures if f.target is not None},
        **(extra or {}),
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(payload, indent=2, default=str) + "\n")
    print(f"wrote {out}")
    return payload
