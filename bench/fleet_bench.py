"""Benchmark of the ways to deploy a fleet: local processes, 3 netns hosts, compose.

    .venv/bin/python bench/fleet_bench.py [--runs N] [--lockstep-duration S]
        [--realtime-duration S] [--only local,hosts3,compose] [--out FILE.json]

For each deployment, Scenario 1 is run ``--runs`` times (≥ 3) in lockstep and in realtime:

* **local** — ``tlfleet run`` (``tlfleet.coordinator.run.run_fleet``: router, sim and agents as
  processes on loopback);
* **hosts3** — ``tlfleet run --hosts 3`` (``tlfleet.coordinator.run_hosts.run_on_hosts``: three
  network namespaces joined by a bridge, one router each, routers connected; root only);
* **compose** — ``docker/compose-run.sh`` on a compose file written by ``tlfleet compose``
  (one container per process on one compose network; the image must be buildable offline, see
  README "docker compose").

Figures, medians over the runs: the lockstep **speed-up** (sim seconds per wall second of the
supervised phase, from ``run.json``) and the realtime frame → command **latency p50 / p99** (the
simulator's ``sim_stats``: command arrival at the sim − publication of the frame it answers, on
the sim's own clock), each also as a ratio to the local run. CPU time (user + system of the
processes this benchmark waited for, ``RUSAGE_CHILDREN``) is given beside the wall time for local
and hosts3; compose containers are not this process's children (n/a).

This machine is shared by several engineers and has 2 cores: realtime latency in particular is
noisy (one p99 sample is one slow wake-up); compare the lockstep speed-up and the CPU first.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tlfleet.coordinator.compose import ComposeConfig, write_compose  # noqa: E402
from tlfleet.coordinator.record.rundir import read_events  # noqa: E402
from tlfleet.coordinator.run import RunConfig, run_fleet  # noqa: E402
from tlfleet.coordinator.run_hosts import run_on_hosts  # noqa: E402

SCENARIO1 = ROOT / "scenarios" / "scenario1.toml"
DEPLOYMENTS = ("local", "hosts3", "compose")


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def one_run(deployment: str, mode: str, duration: float, out: Path) -> dict:
    """One run of Scenario 1; its figures from run.json and the sim_stats event."""
    cpu0, wall0 = children_cpu(), time.monotonic()
    if deployment == "local":
        run_fleet(RunConfig(SCENARIO1, mode=mode, out=out, duration=duration, report=False,
                            rrd=False))
    elif deployment == "hosts3":
        done = run_on_hosts(SCENARIO1, 3, out=out, mode=mode, capture=True,
                            supervise_args=["--duration", repr(duration), "--no-report",
                                            "--no-rrd", "--quiet"],
                            sim_args=["--duration", repr(duration)])
        if done.returncode != 0:
            raise RuntimeError(f"hosts3 run failed: {done.stderr[-2000:]}")
    else:
        compose = write_compose(ComposeConfig(SCENARIO1, out.parent / f"{out.name}.yaml",
                                              mode=mode, duration=duration))
        done = subprocess.run(["bash", str(ROOT / "docker" / "compose-run.sh"), str(compose),
                               str(out)], cwd=ROOT, capture_output=True, text=True,
                              env=dict(os.environ, PYTHON=sys.executable), timeout=1800)
        if done.returncode != 0:
            raise RuntimeError(f"compose run failed: {done.stdout[-1500:]}{done.stderr[-1500:]}")
    total_wall = time.monotonic() - wall0
    info = json.loads((out / "run.json").read_text())
    stats = next((e.data for e in reversed(read_events(out / "events.jsonl", strict=False))
                  if e.kind == "sim_stats"), {})
    return {
        "clean": bool(info.get("clean")), "t_end": info.get("t_end"),
        "wall_time": info.get("wall_time", math.nan),  # [s] the supervised phase
        "speedup": info.get("speedup", math.nan),
        "latency_p50_ms": stats.get("latency_p50_ms", math.nan),
        "latency_p99_ms": stats.get("latency_p99_ms", math.nan),
        "missed": stats.get("missed", 0), "due": stats.get("due", 0),
        "total_wall_s": total_wall,  # [s] including start-up and teardown
        "cpu_s": children_cpu() - cpu0 if deployment != "compose" else math.nan,
    }


def median(runs: list[dict], key: str) -> float:
    values = [r[key] for r in runs if isinstance(r.get(key), (int, float))
              and not math.isnan(r[key])]
    return statistics.median(values) if values else math.nan


def ratio(value: float, reference: float) -> float:
    return value / reference if reference and not math.isnan(reference) else math.nan


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--lockstep-duration", type=float, default=30.0, metavar="S")
    parser.add_argument("--realtime-duration", type=float, default=20.0, metavar="S")
    parser.add_argument("--only", default=",".join(DEPLOYMENTS))
    parser.add_argument("--out", type=Path,
                        default=ROOT / "bench" / "results" / "fleet_bench.json")
    args = parser.parse_args(argv)
    if args.runs < 3:
        parser.error("--runs must be ≥ 3 (medians)")
    chosen = [d for d in DEPLOYMENTS if d in args.only.split(",")]
    runs: dict[str, dict[str, list[dict]]] = {d: {"lockstep": [], "realtime": []} for d in chosen}
    with tempfile.TemporaryDirectory(prefix="fleet-bench-") as tmp:
        for i in range(args.runs):
            for deployment in chosen:  # interleaved: the machine's load hits all alike
                for mode, duration in (("lockstep", args.lockstep_duration),
                                       ("realtime", args.realtime_duration)):
                    out = Path(tmp) / f"{deployment}-{mode}-{i}"
                    result = one_run(deployment, mode, duration, out)
                    runs[deployment][mode].append(result)
                    print(f"{deployment:8s} {mode:8s} run {i + 1}: speed-up "
                          f"{result['speedup']:.2f}, p50 {result['latency_p50_ms']:.2f} ms, "
                          f"p99 {result['latency_p99_ms']:.2f} ms, clean {result['clean']}",
                          flush=True)
    results: dict[str, dict[str, float]] = {}
    for deployment in chosen:
        lock, real = runs[deployment]["lockstep"], runs[deployment]["realtime"]
        results[deployment] = {
            "lockstep_speedup": median(lock, "speedup"),
            "lockstep_wall_s": median(lock, "wall_time"),
            "lockstep_cpu_s": median(lock, "cpu_s"),
            "lockstep_total_wall_s": median(lock, "total_wall_s"),
            "realtime_p50_ms": median(real, "latency_p50_ms"),
            "realtime_p99_ms": median(real, "latency_p99_ms"),
            "all_clean": all(r["clean"] for r in lock + real),
        }
    local = results.get("local", {})
    for figures in results.values():
        for key in ("lockstep_speedup", "realtime_p50_ms", "realtime_p99_ms"):
            figures[f"{key}_vs_local"] = ratio(figures[key], local.get(key, math.nan))
    header = (f"{'deployment':10s} {'lockstep ×':>10s} {'÷local':>7s} {'wall s':>7s} "
              f"{'CPU s':>7s} {'rt p50 ms':>10s} {'÷local':>7s} {'rt p99 ms':>10s} "
              f"{'÷local':>7s} {'clean':>6s}")
    print(f"\nScenario 1, medians of {args.runs} runs (lockstep {args.lockstep_duration:g} s, "
          f"realtime {args.realtime_duration:g} s of sim time); shared 2-core machine: realtime "
          "latency is noisy")
    print(header)
    for deployment, f in results.items():
        print(f"{deployment:10s} {f['lockstep_speedup']:10.2f} "
              f"{f['lockstep_speedup_vs_local']:7.2f} {f['lockstep_wall_s']:7.1f} "
              f"{f['lockstep_cpu_s']:7.1f} {f['realtime_p50_ms']:10.2f} "
              f"{f['realtime_p50_ms_vs_local']:7.2f} {f['realtime_p99_ms']:10.2f} "
              f"{f['realtime_p99_ms_vs_local']:7.2f} {f['all_clean']!s:>6s}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({
        "benchmark": "fleet_bench", "scenario": "scenario1", "runs": args.runs,
        "lockstep_duration_s": args.lockstep_duration,
        "realtime_duration_s": args.realtime_duration,
        "python": platform.python_version(), "machine": platform.machine(),
        "cpus": os.cpu_count(), "results": results, "raw": runs,
        "note": "shared 2-core machine: realtime latency is noisy",
    }, indent=2, default=str) + "\n")
    print(f"\nJSON: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
