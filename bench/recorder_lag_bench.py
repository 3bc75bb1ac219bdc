"""How far the coordinator's recording falls behind the simulator in a lockstep run (issue goal:
at most 0.5 s of sim time at any moment, Scenario 1).

The children run under SCHED_FIFO where this user may (``tlfleet run --sched auto``); the
coordinator, an ordinary task, was starved by them until
:func:`tlfleet.coordinator.launch.processes.share_with_children` put it at their priority for the
supervision. This benchmark measures both arms, interleaved:

* the coordinator's view: every supervision step calls the run's progress callback with the sim
  time of the last frame it recorded; each call is stamped with the wall clock;
* the simulator's view: a probe process, ``tlfleet echo clock`` at SCHED_FIFO priority 3 (above
  the fleet, so it sees each Clock the moment it is sent), stamps every Clock with the wall clock.

At each Clock the probe saw at wall time w, the lag is the Clock's sim time minus the sim time the
coordinator had recorded by w (:func:`lag_series`). Wall clocks are one system clock
(``time.time``), so the two processes' stamps compare directly.

    .venv/bin/python bench/recorder_lag_bench.py [--pairs 2] [--scenario scenario1]
"""

from __future__ import annotations

import argparse
import bisect
import contextlib
import itertools
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import RESULTS, Figure, load_average, report, sorted_quantile

TARGET_LAG = 0.5  # [s] sim time


def lag_series(probe: Sequence[tuple[float, float]],
               coordinator: Sequence[tuple[float, float]]) -> list[float]:
    """For each probe sample (wall w [s], sim time t [s]) after the coordinator's first step,
    t minus the sim time the coordinator had recorded at its last step at or before w (its
    record does not move between steps). Both sequences in wall-clock order."""
    walls = [w for w, _ in coordinator]
    lags = []
    for w, t in probe:
        k = bisect.bisect_right(walls, w) - 1
        if k >= 0:
            lags.append(t - coordinator[k][1])
    return lags


def one_run(scenario: str, share: bool, work: Path) -> dict:
    """One lockstep run with the probe; ``share`` False runs the coordinator as before (an
    ordinary task whatever its children's policy)."""
    from tlfleet.agent.scenario.bundled import resolve_scenario
    from tlfleet.coordinator import run as run_module
    from tlfleet.coordinator.live.supervisor import SupervisorConfig
    from tlfleet.coordinator.run import RunConfig, child_sched, run_fleet

    out = work / f"run-{'share' if share else 'alone'}-{time.monotonic_ns()}"
    config = RunConfig(resolve_scenario(scenario), mode="lockstep", out=out, report=False,
                       rrd=False, supervisor=SupervisorConfig(ready_timeout=60,
                                                              wall_timeout=600))
    steps: list[tuple[float, float]] = []
    probe_lines: list[str] = []
    probe: dict = {}

    def progress(t: float, duration: float) -> None:
        steps.append((time.time(), t))
        if "proc" not in probe and (out / "run.json").is_file():
            command = [sys.executable, "-m", "tlfleet.cli", "echo", "clock", "--run", str(out),
                       "-q"]
            if shutil.which("chrt") and child_sched(config) == "fifo":
                command = ["chrt", "-f", "3", *command]
            probe["proc"] = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
            probe["reader"] = threading.Thread(
                target=lambda: probe_lines.extend(probe["proc"].stdout), daemon=True)
            probe["reader"].start()

    original = run_module.share_with_children
    if not share:
        run_module.share_with_children = lambda *_a, **_k: contextlib.nullcontext(False)
    cpu0 = time.process_time()
    wall0 = time.perf_counter()
    try:
        result = run_fleet(config, progress=progress)
    finally:
        run_module.share_with_children = original
        if "proc" in probe:
            probe["proc"].terminate()
            probe["proc"].wait(timeout=10)
            probe["reader"].join(timeout=10)
    wall = time.perf_counter() - wall0
    seen = [json.loads(line) for line in probe_lines if line.startswith("{")]
    samples = [(s["received"], s["msg"]["t"]) for s in seen if s.get("kind") == "Clock"]
    lags = sorted(lag_series(samples, steps))
    return {"share": share, "sched": child_sched(config), "verdict": result.verdict.label,
            "wall_s": wall, "coordinator_cpu_s": time.process_time() - cpu0,
            "t_end": result.outcome.t_end, "steps": len(steps), "probe_samples": len(samples),
            "lag_max": lags[-1] if lags else float("nan"),
            "lag_p99": sorted_quantile(lags, 0.99), "lag_p50": sorted_quantile(lags, 0.5),
            "longest_step_gap_s": max((b[0] - a[0] for a, b in itertools.pairwise(steps)),
                                      default=float("nan"))}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=2, help="interleaved before/after pairs")
    parser.add_argument("--scenario", default="scenario1")
    parser.add_argument("--out", type=Path, default=RESULTS / "recorder_lag_bench.json")
    args = parser.parse_args(argv)
    load_before = load_average()
    runs = []
    with tempfile.TemporaryDirectory() as folder:
        for pair in range(args.pairs):
            for share in ((False, True) if pair % 2 == 0 else (True, False)):
                row = one_run(args.scenario, share, Path(folder))
                runs.append(row)
                print(f"  {'shared ' if share else 'ordinary'} ({row['sched']}): lag max "
                      f"{row['lag_max']:.3f} s, p99 {row['lag_p99']:.3f} s, p50 "
                      f"{row['lag_p50']:.3f} s; longest gap between supervision steps "
                      f"{row['longest_step_gap_s']:.3f} s; wall {row['wall_s']:.1f} s; "
                      f"{row['probe_samples']} probe samples; {row['verdict']}", flush=True)
    after = [r for r in runs if r["share"]]
    before = [r for r in runs if not r["share"]]

    def median(rows, key):
        return statistics.median(r[key] for r in rows) if rows else float("nan")

    figures = [
        Figure("lag_max_after", "recorder lag behind the sim, max over the run (now) [sim s]",
               median(after, "lag_max"), "s", target=TARGET_LAG),
        Figure("lag_max_before", "the same, coordinator an ordinary task (before)",
               median(before, "lag_max"), "s"),
        Figure("lag_p99_after", "recorder lag p99 (now)", median(after, "lag_p99"), "s"),
        Figure("step_gap_after", "longest pause between supervision steps (now) [wall s]",
               median(after, "longest_step_gap_s"), "s"),
        Figure("step_gap_before", "the same (before)", median(before, "longest_step_gap_s"),
               "s"),
        Figure("wall_after", "run wall time (now)", median(after, "wall_s"), "s"),
        Figure("wall_before", "run wall time (before)", median(before, "wall_s"), "s"),
    ]
    report("recorder_lag_bench", figures, args.out, load_before=load_before,
           extra={"runs": runs, "scenario": args.scenario, "pid": os.getpid()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
