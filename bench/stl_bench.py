"""Benchmark of the STL core (tracker issues 3 and 17): control step, offline monitor, harness.

    .venv/bin/python bench/stl_bench.py [--quick] [--out bench/results/stl_bench.json]

Prints a table (CPU time beside wall time, the load average) and writes JSON
(``bench.common``). Every figure is the median over ``--runs`` runs (≥ 5):

* ``step_us``: CPU µs per control step of an agent whose task couples 3 robots (Scenario 1's
  φ′4, G[5,30] (dist(p4, p3) <= 1 & dist(p4, p5) <= 1)) with 10 neighbours within R = 0.7 m
  (target ≤ 50 µs);
* ``step_obstacles_us``: the same step with tlfleet's defaults (docs/stl-saturation.md) and a
  wall and a pillar within the static avoidance's range (target ≤ 35 µs);
* ``tick3_us``: CPU µs of one 100 Hz tick of Scenario 1's three STL agents (3, 4, 5), each
  stepping on the same frame at t = 31.02 s, in their second sub-tasks (robot 3's φ″3 couples
  3 and 4), plain control steps (no repair, no message);
* ``monitor_ms``: offline standard robustness of one task over **all** 9001 samples (90 s at
  100 Hz; φ′4's ψ under G[0,90], so no sample is trimmed away by the window; target ≤ 3 ms);
* ``harness_speed``: simulated seconds per CPU second for Scenario 1's STL robots (3, 4, 5)
  on the pure harness (90 s).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))  # the closed-loop test harnesses

from stl_harness import run_closed_loop  # noqa: E402
from tlfleet.agent.model.scenario import DiscObstacle, RectObstacle  # noqa: E402
from tlfleet.agent.policy.stl import StepInput, build_agents  # noqa: E402
from tlfleet.agent.scenario.loader import load_scenario  # noqa: E402
from tlfleet.agent.stl.monitor import Trajectory, task_robustness  # noqa: E402
from tlfleet.agent.stl.syntax import Temporal  # noqa: E402

from bench.common import Figure, load_average, report, time_calls  # noqa: E402

TARGETS = {"step_us": 50.0, "step_obstacles_us": 35.0, "monitor_ms": 3.0}
MONITOR_SAMPLES = 9001


def bench_step(runs: int, steps: int) -> tuple[float, float]:
    """CPU and wall µs per step, agent 4 in φ′4 with 10 neighbours within R (no critical event)."""
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
    timing = time_calls(lambda: agent.step(state, StepInput(t, poses)), runs, steps)
    return timing.cpu * 1e6, timing.wall * 1e6


def bench_step_with_obstacles(runs: int, steps: int) -> tuple[float, float]:
    """CPU and wall µs per step as :func:`bench_step`, with tlfleet's defaults (saturation-aware
    funnel, coupled radii for robots 3 and 5, walls and obstacles in eq. (6), routes) and a wall
    and a pillar within the static term's range of robot 4 (docs/stl-saturation.md §8)."""
    base = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    stl = replace(base.stl, saturation_aware=True, rho_opt_from_arena=True, coupled_radii=True,
                  wall_avoidance=True, route_around=True, lookahead=True)
    wall = RectObstacle(-0.5, -0.9, 0.5, -0.75, "wall")  # its face 0.25 m below robot 4's centre
    pillar = DiscObstacle((0.55, 0.3), 0.05, "pillar")  # its surface 0.27 m from robot 4's
    scenario = replace(base, stl=stl, arena=replace(base.arena, obstacles=(wall, pillar)))
    agent = build_agents(scenario, robots=[4], warn=False)[4]
    rng = np.random.default_rng(0)
    poses = {4: (0.0, 0.0, 0.0)}
    ids = [3, 5, *range(10, 18)]
    for k, j in enumerate(ids):
        angle = 2 * math.pi * k / len(ids) + 0.3
        d = rng.uniform(0.62, 0.69)
        poses[j] = (d * math.cos(angle), d * math.sin(angle), 0.0)
    state = agent.initial_state()
    state, _ = agent.step(state, StepInput(0.0, poses))  # activation (funnel, route check)
    t = 0.05  # between two route checks (every 0.5 s), the funnel barely narrowed
    _, out = agent.step(state, StepInput(t, poses))
    if out.log.repair or out.messages:
        raise RuntimeError(f"benchmark step is not a plain control step: {out}")
    if agent.cfg.static is None or not any(agent.cfg.static.rects):
        raise RuntimeError("the benchmark agent has no static term")
    timing = time_calls(lambda: agent.step(state, StepInput(t, poses)), runs, steps)
    return timing.cpu * 1e6, timing.wall * 1e6


def bench_tick3(runs: int, steps: int) -> tuple[float, float]:
    """CPU and wall µs of one tick of Scenario 1's three STL agents on one frame (t = 31 s)."""
    scenario = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    agents = build_agents(scenario, robots=[3, 4, 5], warn=False)
    poses = {r.id: np.array(r.pose, dtype=float) for r in scenario.robots}
    states = {i: a.initial_state() for i, a in agents.items()}
    # activation of the first sub-tasks; their end (t ≥ b = 30); activation of the second ones
    for t in (0.0, 31.0, 31.01):
        for i, a in agents.items():
            states[i], _ = a.step(states[i], StepInput(t, poses))
    t = 31.02
    for i, a in agents.items():
        _, out = a.step(states[i], StepInput(t, poses))
        if out.log.repair or out.messages or not states[i].active:
            raise RuntimeError(f"benchmark tick of robot {i} is not a plain control step: {out}")
    items = [(a, states[i]) for i, a in agents.items()]

    def tick() -> None:
        for a, st in items:
            a.step(st, StepInput(t, poses))

    timing = time_calls(tick, runs, steps)
    return timing.cpu * 1e6, timing.wall * 1e6


def bench_monitor(runs: int) -> tuple[float, float, int]:
    """CPU and wall ms of the offline standard robustness of φ′4's ψ over all 9001 samples."""
    scenario = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    task = build_agents(scenario, robots=[4])[4].cfg.subtasks[0]
    phi = Temporal("G", 0.0, 90.0, task.psi)  # the window covers every sample
    rng = np.random.default_rng(1)
    t = np.arange(MONITOR_SAMPLES) / 100.0
    traj = Trajectory(t, {j: np.cumsum(rng.normal(0, 0.01, (MONITOR_SAMPLES, 3)), axis=0)
                          for j in (3, 4, 5)})
    evaluated = int(traj.window(phi.a, phi.b).sum())
    if evaluated != MONITOR_SAMPLES:
        raise RuntimeError(f"monitor benchmark evaluates {evaluated} samples, not "
                           f"{MONITOR_SAMPLES}")
    timing = time_calls(lambda: task_robustness(phi, traj), runs, 5)
    return timing.cpu * 1e3, timing.wall * 1e3, evaluated


def bench_harness(runs: int, duration: float) -> tuple[float, float]:
    """Simulated s per CPU s and per wall s of Scenario 1's STL robots on the pure harness."""
    scenario = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    poses = {j: scenario.robot(j).pose for j in (3, 4, 5)}
    cpu, wall = [], []
    for _ in range(runs):
        agents = build_agents(scenario, robots=[3, 4, 5], warn=False)
        c0, w0 = time.thread_time(), time.perf_counter()
        run_closed_loop(list(agents.values()), poses, duration)
        cpu.append(duration / (time.thread_time() - c0))
        wall.append(duration / (time.perf_counter() - w0))
    return statistics.median(cpu), statistics.median(wall)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smoke run (fewer steps, 10 s sim)")
    parser.add_argument("--runs", type=int, default=7, help="runs per figure (≥ 5)")
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "stl_bench.json")
    args = parser.parse_args(argv)
    runs = max(5, args.runs)
    steps = 300 if args.quick else 5000
    duration = 10.0 if args.quick else 90.0
    load_before = load_average()
    step_cpu, step_wall = bench_step(runs, steps)
    obstacles_cpu, obstacles_wall = bench_step_with_obstacles(runs, steps)
    tick_cpu, tick_wall = bench_tick3(runs, steps // 3)
    monitor_cpu, monitor_wall, samples = bench_monitor(runs)
    harness_cpu, harness_wall = bench_harness(runs if not args.quick else 5, duration)
    figures = [
        Figure("step_us", "STL control step, 3-robot task, 10 neighbours", step_cpu, "µs",
               TARGETS["step_us"], wall=step_wall),
        Figure("step_obstacles_us", "STL control step, defaults, obstacles in range",
               obstacles_cpu, "µs", TARGETS["step_obstacles_us"], wall=obstacles_wall),
        Figure("tick3_us", "one 100 Hz tick of Scenario 1's 3 STL agents", tick_cpu, "µs",
               wall=tick_wall),
        Figure("monitor_ms", f"offline monitor, 1 task, {samples} samples", monitor_cpu, "ms",
               TARGETS["monitor_ms"], wall=monitor_wall),
        Figure("harness_speed", "harness, Scenario 1 STL robots (sim s per s)", harness_cpu,
               "×", wall=harness_wall),
    ]
    report("stl_bench", figures, args.out, load_before=load_before, quick=args.quick,
           extra={"runs": runs, "steps_per_run": steps, "monitor_samples": samples,
                  "harness_duration_s": duration,
                  "units": {"step_us": "CPU µs/step", "tick3_us": "CPU µs/tick",
                            "monitor_ms": "CPU ms", "harness_speed": "sim s / CPU s"}})
    return 0


if __name__ == "__main__":
    sys.exit(main())
