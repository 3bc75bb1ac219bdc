"""Benchmark of the secured fleet: mutual TLS + the router's ACL against plain TCP.

    .venv/bin/python bench/security_bench.py [--quick] [--runs N] [--baseline TRAJECTORY.csv]
                                             [--out FILE.json]

Scenario 1 through ``tlfleet.coordinator.run.run_fleet`` (router, sim and one process per robot, as
``tlfleet run``), plain and secured (``secure=`` a key directory of ``tlfleet keys``) in
alternation — plain, secured, plain, secured … — so that the load the other users of a shared
machine put on it falls on both alike. Per pair and as medians over ``--runs`` (≥ 3):

* lockstep speed-up (sim s per wall s of the supervised phase), secured / plain (target ≥ 0.9:
  the security costs ≤ 10 %);
* realtime frame→command latency p99 (the sim's ``sim_stats``), secured / plain (target ≤ 1.1);
* CPU per process role (``psutil`` user + system per wall second, % of one core) — the figure
  least disturbed by the machine's load; the router pays for TLS, the ACL and reading its own
  ACL trace (``tlfleet.sim.router.denials``);
* attribution: a third lockstep run per pair, secured with the router's ACL trace off
  (``RUST_LOG=warn`` in the children's environment: zenoh's own filter wins over the router's,
  so no denial is logged) — what the denial log costs, beside TLS and the ACL themselves;
* whether every secured lockstep trajectory is byte-identical to the plain ones (and to
  ``--baseline``, e.g. a run of the original code).

The 1-minute load average is recorded before every run (``os.getloadavg``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from common import Figure, figure_records, load_average  # noqa: E402
from runtime_bench import CpuSampler  # noqa: E402
from tlfleet.agent.scenario import load_scenario  # noqa: E402
from tlfleet.coordinator.live.supervisor import SupervisorConfig  # noqa: E402
from tlfleet.coordinator.record.rundir import read_events  # noqa: E402
from tlfleet.coordinator.run import RunConfig, run_fleet  # noqa: E402
from tlfleet.coordinator.security.authority import write_keys  # noqa: E402

SCENARIO1 = ROOT / "scenarios" / "scenario1.toml"
TARGETS = {"lockstep_speedup_ratio": 0.9, "latency_p99_ratio": 1.1}


def run_once(mode: str, duration: float, out: Path, secure: Path | None,
             acl_trace: bool = True) -> dict:
    load = os.getloadavg()[0]
    marks: list[float] = []
    saved = os.environ.get("RUST_LOG")
    if not acl_trace:
        os.environ["RUST_LOG"] = "warn"  # inherited by the children started by run_fleet
    try:
        with CpuSampler() as sampler:
            result = run_fleet(RunConfig(SCENARIO1, mode=mode, out=out, duration=duration,
                                         seed=1, secure=secure, report=False, figures=False,
                                         rrd=False, supervisor=SupervisorConfig(
                                             ready_timeout=120.0,
                                             wall_timeout=20 * duration + 120)),
                               progress=lambda _t, _total: marks.append(time.monotonic()))
    finally:
        if saved is None:
            os.environ.pop("RUST_LOG", None)
        else:
            os.environ["RUST_LOG"] = saved
    cpu = sampler.cpu_pct(marks[0] + 0.5, marks[-1]) if len(marks) >= 2 else {}
    stats = next((e.data for e in reversed(read_events(out / "events.jsonl", strict=False))
                  if e.kind == "sim_stats"), {})
    return {
        "secure": secure is not None, "acl_trace": acl_trace, "mode": mode,
        "clean": result.clean,
        "reason": result.outcome.reason, "load_1min": load,
        "wall_time": result.info.get("wall_time", math.nan),
        "speedup": result.info.get("speedup", math.nan),
        "latency_p50_ms": stats.get("latency_p50_ms", math.nan),
        "latency_p99_ms": stats.get("latency_p99_ms", math.nan),
        "missed": stats.get("missed", 0), "due": stats.get("due", 0),
        "cpu_pct": cpu, "trajectory": str(out / "trajectory.csv"),
    }


def show(name: str, row: dict) -> None:
    print(f"  {name:<22} clean={row['clean']!s:<5} speed-up {row['speedup']:.2f}×  p99 "
          f"{row['latency_p99_ms']:.2f} ms  load {row['load_1min']:.1f}  router CPU "
          f"{row['cpu_pct'].get('router', math.nan):.1f} %", flush=True)


def median(runs: list[dict], key: str) -> float:
    values = [r[key] for r in runs if not math.isnan(r[key])]
    return statistics.median(values) if values else math.nan


def cpu_median(runs: list[dict], role: str) -> float:
    values = [r["cpu_pct"][role] for r in runs if role in r["cpu_pct"]]
    return statistics.median(values) if values else math.nan


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="lockstep 30 s, realtime 10 s")
    parser.add_argument("--runs", type=int, default=3, help="pairs per mode (≥ 3)")
    parser.add_argument("--baseline", type=Path, default=None,
                        help="a lockstep trajectory.csv of Scenario 1 (seed 1, same duration) "
                             "to compare the secured ones with")
    parser.add_argument("--out", type=Path,
                        default=ROOT / "bench" / "results" / "security_bench.json")
    args = parser.parse_args(argv)
    runs = max(3, args.runs)
    lockstep_s, realtime_s = (30.0, 10.0) if args.quick else (90.0, 30.0)
    started = time.monotonic()
    load_before = load_average()
    per_run: dict[str, list[dict]] = {"lockstep": [], "realtime": [], "lockstep_no_trace": []}
    with tempfile.TemporaryDirectory(prefix="security_bench-") as tmp:
        tmpdir = Path(tmp)
        keydir = tmpdir / "keys"
        write_keys(load_scenario(SCENARIO1), keydir)
        for k in range(runs):
            for mode, duration in (("lockstep", lockstep_s), ("realtime", realtime_s)):
                for secure in (None, keydir):
                    name = f"{mode}-{'tls' if secure else 'tcp'}-{k}"
                    row = run_once(mode, duration, tmpdir / name, secure)
                    per_run[mode].append(row)
                    show(name, row)
            row = run_once("lockstep", lockstep_s, tmpdir / f"lockstep-tls-notrace-{k}", keydir,
                           acl_trace=False)
            per_run["lockstep_no_trace"].append(row)
            show(f"lockstep-tls-notrace-{k}", row)
        lock = per_run["lockstep"]
        plain_traj = [Path(r["trajectory"]).read_bytes() for r in lock if not r["secure"]]
        secure_traj = [Path(r["trajectory"]).read_bytes()
                       for r in lock + per_run["lockstep_no_trace"] if r["secure"]]
        identical = all(t == plain_traj[0] for t in plain_traj + secure_traj)
        baseline_identical = None
        if args.baseline is not None:
            reference = args.baseline.read_bytes()
            baseline_identical = all(t == reference for t in secure_traj)
    split = {mode: ([r for r in per_run[mode] if not r["secure"]],
                    [r for r in per_run[mode] if r["secure"]]) for mode in ("lockstep", "realtime")}
    notrace = per_run["lockstep_no_trace"]
    lp, ls = split["lockstep"]
    rp, rs = split["realtime"]
    pair_speed = [s["speedup"] / p["speedup"] for p, s in zip(lp, ls, strict=True)]
    pair_p99 = [s["latency_p99_ms"] / p["latency_p99_ms"] for p, s in zip(rp, rs, strict=True)]
    results = {
        "lockstep_speedup_plain": median(lp, "speedup"),
        "lockstep_speedup_secure": median(ls, "speedup"),
        "lockstep_speedup_ratio": median(ls, "speedup") / median(lp, "speedup"),
        "lockstep_speedup_ratio_pairs_median": statistics.median(pair_speed),
        "lockstep_speedup_secure_no_acl_trace": median(notrace, "speedup"),
        "lockstep_speedup_ratio_no_acl_trace": median(notrace, "speedup")
        / median(lp, "speedup"),
        "router_cpu_pct_lockstep_secure_no_acl_trace": cpu_median(notrace, "router"),
        "latency_p99_ms_plain": median(rp, "latency_p99_ms"),
        "latency_p99_ms_secure": median(rs, "latency_p99_ms"),
        "latency_p99_ratio": median(rs, "latency_p99_ms") / median(rp, "latency_p99_ms"),
        "latency_p99_ratio_pairs_median": statistics.median(pair_p99),
        "latency_p50_ms_plain": median(rp, "latency_p50_ms"),
        "latency_p50_ms_secure": median(rs, "latency_p50_ms"),
        "cpu_pct": {f"{mode}_{which}": {role: cpu_median(rows, role)
                                        for role in ("router", "sim", "agent")}
                    for mode in ("lockstep", "realtime")
                    for which, rows in zip(("plain", "secure"), split[mode], strict=True)},
        "lockstep_trajectories_identical": identical,
        "secure_identical_to_baseline": baseline_identical,
        "all_clean": all(r["clean"] for rows in per_run.values() for r in rows),
        "load_1min": [r["load_1min"] for rows in per_run.values() for r in rows],
    }
    figures = [  # the two targets, in the layout bench/summary.py reads (bench/common.py)
        Figure("lockstep_speedup_ratio", "secured / plain lockstep speed-up (Scenario 1)",
               results["lockstep_speedup_ratio"], "x", TARGETS["lockstep_speedup_ratio"],
               "higher"),
        Figure("latency_p99_ratio", "secured / plain realtime latency p99 (Scenario 1)",
               results["latency_p99_ratio"], "x", TARGETS["latency_p99_ratio"], "lower")]
    meets = {f.key: f.met for f in figures}
    print(f"security_bench ({'quick' if args.quick else 'full'}: lockstep {lockstep_s:g} s, "
          f"realtime {realtime_s:g} s; median of {runs} pairs; python "
          f"{platform.python_version()}; load 1-min {min(results['load_1min']):.1f}–"
          f"{max(results['load_1min']):.1f} on {os.cpu_count()} cores; "
          f"{time.monotonic() - started:.0f} s)")
    print(f"{'measure':<44} {'plain':>9} {'secured':>9} {'ratio':>7} {'target':>7}  met")
    print(f"{'Scenario 1 lockstep speed-up [×]':<44} {results['lockstep_speedup_plain']:>9.2f} "
          f"{results['lockstep_speedup_secure']:>9.2f} {results['lockstep_speedup_ratio']:>7.3f} "
          f"{'≥ 0.9':>7}  {'yes' if meets['lockstep_speedup_ratio'] else 'NO'}")
    print(f"{'  … secured, router ACL trace off':<44} {'':>9} "
          f"{results['lockstep_speedup_secure_no_acl_trace']:>9.2f} "
          f"{results['lockstep_speedup_ratio_no_acl_trace']:>7.3f}")
    print(f"{'Scenario 1 realtime latency p99 [ms]':<44} {results['latency_p99_ms_plain']:>9.2f} "
          f"{results['latency_p99_ms_secure']:>9.2f} {results['latency_p99_ratio']:>7.3f} "
          f"{'≤ 1.1':>7}  {'yes' if meets['latency_p99_ratio'] else 'NO'}")
    print(f"{'Scenario 1 realtime latency p50 [ms]':<44} {results['latency_p50_ms_plain']:>9.2f} "
          f"{results['latency_p50_ms_secure']:>9.2f} "
          f"{results['latency_p50_ms_secure'] / results['latency_p50_ms_plain']:>7.3f}")
    for mode in ("lockstep", "realtime"):
        for role in ("router", "sim", "agent"):
            a = results["cpu_pct"][f"{mode}_plain"][role]
            b = results["cpu_pct"][f"{mode}_secure"][role]
            print(f"{f'{mode}: CPU per {role} process [% of a core]':<44} {a:>9.1f} {b:>9.1f} "
                  f"{b / a if a else math.nan:>7.3f}")
    print(f"{'lockstep: CPU of the router, ACL trace off':<44} {'':>9} "
          f"{results['router_cpu_pct_lockstep_secure_no_acl_trace']:>9.1f}")
    print(f"per-pair ratios: speed-up {[round(x, 3) for x in pair_speed]}, "
          f"p99 {[round(x, 3) for x in pair_p99]}")
    print(f"secured lockstep trajectories byte-identical to the plain ones: {identical}"
          + ("" if baseline_identical is None
             else f"; to {args.baseline}: {baseline_identical}"))
    payload = {"benchmark": "security_bench", "quick": args.quick, "runs": runs,
               "python": platform.python_version(), "machine": platform.machine(),
               "cores": os.cpu_count(), "load_average_before": list(load_before),
               "load_average_after": list(load_average()),
               "figures": figure_records(figures),
               "results": results,
               "targets": TARGETS, "meets_targets": meets,
               "durations_s": {"lockstep": lockstep_s, "realtime": realtime_s},
               "per_run": per_run,
               "units": {"speedup": "sim s / wall s", "latency": "ms",
                         "cpu_pct": "% of one core (user + system)"}}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(payload, indent=2, default=str) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
