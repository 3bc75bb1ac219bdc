"""Benchmark of the STL core (tracker issue 3): control step, offline monitor, closed-loop harness.

    .venv/bin/python bench/stl_bench.py [--quick] [--out bench/results/stl_bench.json]

Prints a table and writes JSON. Every figure is the median over ``--runs`` runs (≥ 5):

* ``step_us``: µs per control step of an agent whose task couples 3 robots (Scenario 1's φ′4,
  G[5,30] (dist(p4, p3) <= 1 & dist(p4, p5) <= 1)) with 10 neighbours within R = 0.7 m
  (target ≤ 50 µs);
* ``monitor_ms``: offline standard robustness of one task over 9001 samples (90 s at 100 Hz,
  target ≤ 3 ms);
* ``harness_speed``: simulated seconds per wall second for Scenario 1's STL robots (3, 4, 5)
  on the pure harness (90 s).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from agent.scenario.loader import load_scenario  # noqa: E402
from agent.stl.agent import StepInput, build_agents  # noqa: E402
from agent.stl.harness import run_closed_loop  # noqa: E402
from agent.stl.monitor import Trajectory, task_robustness  # noqa: E402

TARGETS = {"step_us": 50.0, "monitor_ms": 3.0}


def bench_step(runs: int, steps: int) -> float:
    """Median µs per step, agent 4 in φ′4 with 10 neighbours within R (no critical event)."""
    scenario = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    agent = build_agents(scenario, robots=[4])[4]
    rng = np.random.default_rng(0)
    poses = {4: np.array([0.0, 0.0, 0.0])}
    # 10 neighbours on a ring at 0.62–0.69 m (inside R = 0.7, outside R1 = 0.6): robots 3 and 5
    # (task partners) and 8 extra ones (LTL robots or others).
    ids = [3, 5, *range(10, 18)]
    for k, j in enumerate(ids):
        angle = 2 * math.pi * k / len(ids)
        d = rng.uniform(0.62, 0.69)
        poses[j] = np.array([d * math.cos(angle), d * math.sin(angle), 0.0])
    state = agent.initial_state()
    state, _ = agent.step(state, StepInput(0.0, poses))  # activation (funnel init)
    t = 0.5
    _, out = agent.step(state, StepInput(t, poses))
    if out.log.repair or out.messages:
        raise RuntimeError(f"benchmark step is not a plain control step: {out}")
    per_run = []
    for _ in range(runs):
        start = time.perf_counter()
        for _ in range(steps):
            agent.step(state, StepInput(t, poses))
        per_run.append((time.perf_counter() - start) / steps * 1e6)
    return statistics.median(per_run)


def bench_monitor(runs: int) -> float:
    """Median ms of the offline standard robustness of φ′4 over 9001 samples."""
    scenario = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    task = build_agents(scenario, robots=[4])[4].cfg.subtasks[0]
    rng = np.random.default_rng(1)
    t = np.arange(9001) / 100.0
    traj = Trajectory(t, {j: np.cumsum(rng.normal(0, 0.01, (9001, 3)), axis=0)
                          for j in (3, 4, 5)})
    per_run = []
    for _ in range(runs):
        start = time.perf_counter()
        task_robustness(task, traj)
        per_run.append((time.perf_counter() - start) * 1e3)
    return statistics.median(per_run)


def bench_harness(runs: int, duration: float) -> float:
    """Median simulated s per wall s of Scenario 1's STL robots on the pure harness."""
    scenario = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    poses = {j: scenario.robot(j).pose for j in (3, 4, 5)}
    per_run = []
    for _ in range(runs):
        agents = build_agents(scenario, robots=[3, 4, 5], warn=False)
        start = time.perf_counter()
        run_closed_loop(list(agents.values()), poses, duration)
        per_run.append(duration / (time.perf_counter() - start))
    return statistics.median(per_run)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smoke run (fewer steps, 10 s sim)")
    parser.add_argument("--runs", type=int, default=7, help="runs per figure (≥ 5)")
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "stl_bench.json")
    args = parser.parse_args(argv)
    runs = max(5, args.runs)
    steps = 300 if args.quick else 5000
    duration = 10.0 if args.quick else 90.0
    results = {
        "step_us": bench_step(runs, steps),
        "monitor_ms": bench_monitor(runs),
        "harness_speed": bench_harness(runs if not args.quick else 5, duration),
    }
    rows = [
        ("control step, 3-robot task, 10 neighbours", f"{results['step_us']:.1f} µs", "≤ 50 µs"),
        ("offline monitor, 1 task, 9001 samples", f"{results['monitor_ms']:.3f} ms", "≤ 3 ms"),
        ("harness, Scenario 1 STL robots", f"{results['harness_speed']:.0f}× real time", "-"),
    ]
    print(f"stl_bench ({'quick' if args.quick else 'full'}, median of {runs} runs, "
          f"python {platform.python_version()})")
    print(f"{'measure':<45} {'value':>18} {'target':>8}")
    for name, value, target in rows:
        print(f"{name:<45} {value:>18} {target:>8}")
    payload = {
        "quick": args.quick,
        "runs": runs,
        "python": platform.python_version(),
        "machine": platform.machine(),
        "results": results,
        "targets": TARGETS,
        "meets_targets": {k: results[k] <= v for k, v in TARGETS.items()},
        "units": {"step_us": "µs/step", "monitor_ms": "ms", "harness_speed": "sim s / wall s"},
        "harness_duration_s": duration,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(payload, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
