"""Benchmark of the distributed runtime (tracker issue 5 §6): real processes on loopback.

    .venv/bin/python bench/runtime_bench.py [--quick] [--runs N] [--out FILE.json]

Every fleet is started by ``coordinator.runner.run_fleet`` (router + sim + one process per agent,
exactly as ``tlfleet run``); the figures come from the simulator's ``sim_stats`` event
(``sim.stats``: latency = command arrival at the sim − publication of the frame it answers, on the
sim's own clock; a control deadline of robot r at tick k is missed when its ``Command(seq=k)`` has
not arrived when the sim steps past tick k) and from the coordinator's run record. Medians over
``--runs`` runs (≥ 3):

* ``latency_p50_ms`` / ``latency_p99_ms``: Scenario 1 in realtime (target p99 ≤ 2 ms), over
  every command; ``stl_latency_p99_ms``: the worst per-robot p99 of its STL robots (the LTL
  agents answer 1 frame in 20, so their slower steps are about 3 % of the commands and set the
  fleet's p99);
* ``missed_fraction``: missed control deadlines / due ones, same runs (target ≤ 0.1 %);
* ``lockstep_speedup``: Scenario 1 in lockstep, sim seconds per wall second of the supervised
  phase (target ≥ 5×);
* ``max_fleet``: the largest generated fleet of STL robots (omni, a reach task each, on a grid)
  whose realtime runs at 100 Hz miss ≤ 1 % of their deadlines (median over the runs; sizes
  tried in ``--sizes`` order, stopping at the first that fails; target ≥ 30).

Besides, for every run, the CPU time of each child process per wall second of the supervised
phase (``psutil`` user + system, sampled every 0.25 s; ``cpu_pct``: mean per role, % of one
core). Wall-clock figures (latency, missed deadlines) depend on whatever else the machine runs;
CPU per process much less so, which makes it the figure to compare changes with on a shared
machine. Realtime tick 0 owes no command (``sim.stats``), so a run misses nothing by
construction.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from agent.scenario import load_scenario  # noqa: E402
from coordinator.rundir import read_events  # noqa: E402
from coordinator.runner import RunConfig, run_fleet  # noqa: E402
from coordinator.supervisor import SupervisorConfig  # noqa: E402

SCENARIO1 = ROOT / "scenarios" / "scenario1.toml"
TARGETS = {"latency_p99_ms": 2.0, "missed_fraction": 0.001, "lockstep_speedup": 5.0,
           "max_fleet": 30}
FLEET_MISS_LIMIT = 0.01


def generated_fleet(n: int, duration: float) -> str:
    """TOML of ``n`` omni robots on a grid in the 7 m × 7 m arena, each with
    ``F[a,b] (dist(p_i, goal_i) <= 0.1)``, goal 0.3 m to the right of the start."""
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    spacing = min(6.0 / max(cols, 1), 6.0 / max(rows, 1))
    a, b = 0.3 * duration, 0.9 * duration
    lines = [f'name = "fleet{n}"', f"duration = {duration}", "[sim]", "seed = 1"]
    for i in range(n):
        x = -3.0 + spacing * (i % cols + 0.5) - 0.15
        y = -3.0 + spacing * (i // cols + 0.5)
        lines += ["[[robots]]", f"id = {i + 1}", 'kind = "omni"', f"pose = [{x:.3f}, {y:.3f}, 0.0]",
                  f'stl = ["F[{a:g},{b:g}] (dist(p{i + 1}, [{x + 0.3:.3f}, {y:.3f}]) <= 0.1)"]']
    return "\n".join(lines) + "\n"


class CpuSampler:
    """Samples the CPU time (user + system [s]) of every descendant process, by role (the
    ``tlfleet`` subcommand: router, sim, agent), in a background thread."""

    def __init__(self, period: float = 1.0):  # [s]; every sample scans /proc: keep it rare
        self.period = period
        self.samples: dict[int, tuple[str, list[tuple[float, float]]]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="cpu-sampler", daemon=True)

    def __enter__(self) -> CpuSampler:
        self._thread.start()
        return self

    def __exit__(self, *_exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        me = psutil.Process()
        procs: dict[int, tuple[psutil.Process, str]] = {}
        while not self._stop.is_set():
            now = time.monotonic()
            try:
                children = me.children(recursive=True)
            except psutil.Error:
                children = []
            for child in children:
                if child.pid not in procs:
                    try:
                        argv = child.cmdline()
                    except psutil.Error:
                        continue
                    if "cli.main" in argv[:-1]:
                        procs[child.pid] = (child, argv[argv.index("cli.main") + 1])
            for pid, (proc, role) in list(procs.items()):
                try:
                    times = proc.cpu_times()
                except psutil.Error:
                    del procs[pid]
                    continue
                self.samples.setdefault(pid, (role, []))[1].append(
                    (now, times.user + times.system))
            self._stop.wait(self.period)

    def cpu_pct(self, begin: float, end: float) -> dict[str, float]:
        """Mean CPU per process of each role over [begin, end] (monotonic [s]), % of a core."""
        per_role: dict[str, list[float]] = {}
        for role, series in self.samples.values():
            inside = [(t, c) for t, c in series if begin <= t <= end]
            if len(inside) >= 2 and inside[-1][0] > inside[0][0]:
                (t0, c0), (t1, c1) = inside[0], inside[-1]
                per_role.setdefault(role, []).append(100.0 * (c1 - c0) / (t1 - t0))
        return {role: statistics.mean(v) for role, v in sorted(per_role.items())}


def run_once(scenario: Path, mode: str, duration: float, out: Path,
             ready_timeout: float = 120.0) -> dict:
    """One run; its sim_stats, the coordinator's wall time and speed-up, CPU per role."""
    stl_ids = {r.id for r in load_scenario(scenario).robots if r.is_stl}
    marks: list[float] = []
    with CpuSampler() as sampler:
        result = run_fleet(RunConfig(scenario, mode=mode, out=out, duration=duration,
                                     supervisor=SupervisorConfig(
                                         ready_timeout=ready_timeout,
                                         wall_timeout=20 * duration + 120)),
                           progress=lambda _t, _total: marks.append(time.monotonic()))
    cpu = sampler.cpu_pct(marks[0] + 0.5, marks[-1]) if len(marks) >= 2 else {}
    stats = next((e.data for e in reversed(read_events(out / "events.jsonl", strict=False))
                  if e.kind == "sim_stats"), {})
    due = stats.get("due", 0)
    return {
        "clean": result.clean, "reason": result.outcome.reason, "t_end": result.outcome.t_end,
        "wall_time": result.info.get("wall_time", math.nan),
        "ready_time": result.info.get("ready_time", math.nan),
        "speedup": result.info.get("speedup", math.nan),
        "latency_p50_ms": stats.get("latency_p50_ms", math.nan),
        "latency_p99_ms": stats.get("latency_p99_ms", math.nan),
        "latency_p99_ms_by_robot": stats.get("latency_p99_ms_by_robot", {}),
        "stl_latency_p99_ms": max((v for r, v in stats.get("latency_p99_ms_by_robot", {}).items()
                                   if int(r) in stl_ids), default=math.nan),
        "due": due, "missed": stats.get("missed", 0),
        "missed_fraction": stats.get("missed", 0) / due if due else math.nan,
        "cpu_pct": cpu,
        "agent_cpu_pct": cpu.get("agent", math.nan), "sim_cpu_pct": cpu.get("sim", math.nan),
        "router_cpu_pct": cpu.get("router", math.nan),
    }


def median(runs: list[dict], key: str) -> float:
    values = [r[key] for r in runs if not math.isnan(r[key])]
    return statistics.median(values) if values else math.nan


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="short runs (realtime 10 s, lockstep 30 s, fleets 6 s)")
    parser.add_argument("--runs", type=int, default=3, help="runs per figure (≥ 3)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 2, 5, 10, 20, 30, 40],
                        help="generated fleet sizes to try, in order")
    parser.add_argument("--out", type=Path,
                        default=ROOT / "bench" / "results" / "runtime_bench.json")
    args = parser.parse_args(argv)
    runs = max(3, args.runs)
    realtime_s, lockstep_s, fleet_s = (10.0, 30.0, 6.0) if args.quick else (30.0, 90.0, 10.0)
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="runtime_bench-") as tmp:
        tmpdir = Path(tmp)
        realtime = [run_once(SCENARIO1, "realtime", realtime_s, tmpdir / f"rt{k}")
                    for k in range(runs)]
        lockstep = [run_once(SCENARIO1, "lockstep", lockstep_s, tmpdir / f"ls{k}")
                    for k in range(runs)]
        fleets: dict[int, list[dict]] = {}
        max_fleet = 0
        for n in args.sizes:
            path = tmpdir / f"fleet{n}.toml"
            path.write_text(generated_fleet(n, fleet_s))
            fleets[n] = [run_once(path, "realtime", fleet_s, tmpdir / f"fleet{n}-{k}")
                         for k in range(runs)]
            miss = median(fleets[n], "missed_fraction")
            print(f"  fleet of {n:>3} STL robots: missed {100 * miss:.2f} % (median of {runs}), "
                  f"ready in {median(fleets[n], 'ready_time'):.1f} s, CPU per agent "
                  f"{median(fleets[n], 'agent_cpu_pct'):.1f} %, sim "
                  f"{median(fleets[n], 'sim_cpu_pct'):.1f} %, router "
                  f"{median(fleets[n], 'router_cpu_pct'):.1f} % of a core", flush=True)
            if not miss <= FLEET_MISS_LIMIT or not all(r["clean"] for r in fleets[n]):
                break
            max_fleet = n
    results = {
        "latency_p50_ms": median(realtime, "latency_p50_ms"),
        "latency_p99_ms": median(realtime, "latency_p99_ms"),
        "stl_latency_p99_ms": median(realtime, "stl_latency_p99_ms"),
        "missed_fraction": median(realtime, "missed_fraction"),
        "lockstep_speedup": median(lockstep, "speedup"),
        "max_fleet": max_fleet,
        "agent_cpu_pct": median(realtime, "agent_cpu_pct"),
        "sim_cpu_pct": median(realtime, "sim_cpu_pct"),
    }
    meets = {
        "latency_p99_ms": results["latency_p99_ms"] <= TARGETS["latency_p99_ms"],
        "missed_fraction": results["missed_fraction"] <= TARGETS["missed_fraction"],
        "lockstep_speedup": results["lockstep_speedup"] >= TARGETS["lockstep_speedup"],
        "max_fleet": results["max_fleet"] >= TARGETS["max_fleet"],
    }
    rows = [
        ("Scenario 1 realtime: frame→command latency p50",
         f"{results['latency_p50_ms']:.2f} ms", "-"),
        ("Scenario 1 realtime: frame→command latency p99",
         f"{results['latency_p99_ms']:.2f} ms", "≤ 2 ms"),
        ("  the STL robots alone (worst robot's p99)",
         f"{results['stl_latency_p99_ms']:.2f} ms", "-"),
        ("Scenario 1 realtime: missed control deadlines",
         f"{100 * results['missed_fraction']:.3f} %", "≤ 0.1 %"),
        ("Scenario 1 lockstep: speed-up over real time",
         f"{results['lockstep_speedup']:.1f}×", "≥ 5×"),
        ("largest STL fleet at 100 Hz with ≤ 1 % missed", f"{results['max_fleet']} robots",
         "≥ 30"),
        ("Scenario 1 realtime: CPU per agent process",
         f"{results['agent_cpu_pct']:.1f} %", "-"),
        ("Scenario 1 realtime: CPU of the simulator", f"{results['sim_cpu_pct']:.1f} %", "-"),
    ]
    print(f"runtime_bench ({'quick' if args.quick else 'full'}, median of {runs} runs, "
          f"python {platform.python_version()}, {time.monotonic() - started:.0f} s)")
    print(f"{'measure':<50} {'value':>12} {'target':>8}  met")
    met = [None, meets["latency_p99_ms"], None, meets["missed_fraction"],
           meets["lockstep_speedup"], meets["max_fleet"], None, None]
    for (name, value, target), ok in zip(rows, met, strict=True):
        print(f"{name:<50} {value:>12} {target:>8}  {'' if ok is None else 'yes' if ok else 'NO'}")
    payload = {
        "quick": args.quick, "runs": runs, "python": platform.python_version(),
        "machine": platform.machine(), "results": results, "targets": TARGETS,
        "meets_targets": meets,
        "durations_s": {"realtime": realtime_s, "lockstep": lockstep_s, "fleet": fleet_s},
        "per_run": {"realtime": realtime, "lockstep": lockstep,
                    "fleets": {str(n): r for n, r in fleets.items()}},
        "units": {"latency_p50_ms": "ms", "latency_p99_ms": "ms", "missed_fraction": "fraction",
                  "lockstep_speedup": "sim s / wall s", "max_fleet": "robots",
                  "agent_cpu_pct": "% of one core (user + system)",
                  "sim_cpu_pct": "% of one core (user + system)"},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(payload, indent=2, default=str) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
