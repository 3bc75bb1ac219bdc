"""The run record over many runs: verdicts and start-up events (what a scenario author reads).

    .venv/bin/python bench/record_bench.py [--runs 30] [--scenario scenarios/scenario1.toml]
        [--duration S] [--mode lockstep|realtime] [--out FILE.json]

Runs the scenario ``--runs`` times as a real fleet (``tlfleet.coordinator.run.run_fleet``, as
``tlfleet run``; no report, figures or run.rrd) and counts, over every run:

* the verdicts (``outcome``): a lockstep run of a paper scenario is expected ``clean`` every time
  (a false end-of-run ``degraded`` failed ``make run`` in 1 of 21 Scenario 1 runs);
* the start-up events in ``events.jsonl``: one ``plan_ready`` per LTL robot, and the
  ``coupling_limits`` of each LTL robot that STL tasks depend on — made before the start, so the
  ones the coordinator never saw (2 of 13 were recorded) show here;
* events marked ``after_sim_done`` (said once the mission ended; never in the verdict).

Lockstep is deterministic in its trajectory whatever the load; what these figures test is the
machinery around it (timing at the end of a run, the routes at its start), which the load does
move: the table carries the load average. Prints the table, writes
``bench/results/record_bench.json``.
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tlfleet.agent.scenario import load_scenario  # noqa: E402
from tlfleet.coordinator.live.supervisor import SupervisorConfig  # noqa: E402
from tlfleet.coordinator.run import RunConfig, run_fleet  # noqa: E402

from bench.common import RESULTS, Figure, load_average, report  # noqa: E402


def expected_startup(scenario_path: Path) -> collections.Counter[tuple[str, str]]:
    """(source, kind) → count of the start-up events every run must record."""
    from tlfleet.agent.policy.coupling import CouplingModel

    scenario = load_scenario(scenario_path)
    out: collections.Counter[tuple[str, str]] = collections.Counter()
    for robot in scenario.robots:
        if robot.is_ltl:
            out[(f"agent/{robot.id}", "plan_ready")] += 1
            if scenario.navigation.coupling_aware and CouplingModel.from_scenario(scenario,
                                                                                   robot.id):
                out[(f"agent/{robot.id}", "coupling_limits")] += 1
    return out


def one_run(scenario_path: Path, out: Path, mode: str, duration: float | None) -> dict:
    config = RunConfig(scenario_path=scenario_path, mode=mode, out=out, duration=duration,
                       report=False, figures=False, rrd=False,
                       supervisor=SupervisorConfig(ready_timeout=60.0, wall_timeout=600.0))
    t0 = time.perf_counter()
    result = run_fleet(config, report=lambda _text: None)
    wall = time.perf_counter() - t0
    startup: collections.Counter[tuple[str, str]] = collections.Counter()
    after_end = 0
    with open(out / "events.jsonl", encoding="utf-8") as handle:
        for line in handle:
            event = json.loads(line)
            if event["kind"] in ("plan_ready", "coupling_limits") and \
                    not event["data"].get("replan"):
                startup[(event["source"], event["kind"])] += 1
            after_end += bool(event["data"].get("after_sim_done"))
    return {"verdict": result.verdict.label, "reasons": list(result.verdict.reasons),
            "startup": {f"{s} {k}": n for (s, k), n in startup.items()},
            "after_sim_done": after_end, "wall": wall, "load": load_average()[0]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=30)
    parser.add_argument("--scenario", type=Path, default=ROOT / "scenarios" / "scenario1.toml")
    parser.add_argument("--duration", type=float, default=None)
    parser.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    parser.add_argument("--out", type=Path, default=RESULTS / "record_bench.json")
    parser.add_argument("--keep", type=Path, default=None, metavar="DIR",
                        help="keep the run directories of the runs not clean under DIR")
    args = parser.parse_args(argv)
    load_before = load_average()
    expected = expected_startup(args.scenario)
    rows = []
    with tempfile.TemporaryDirectory(prefix="record_bench_") as tmp:
        for k in range(args.runs):
            row = one_run(args.scenario, Path(tmp) / f"run{k}", args.mode, args.duration)
            rows.append(row)
            if args.keep is not None and row["verdict"] != "clean":
                import shutil

                shutil.copytree(Path(tmp) / f"run{k}", args.keep / f"run{k}")
            print(f"run {k + 1}/{args.runs}: {row['verdict']} {row['reasons']} "
                  f"startup {row['startup']} after_sim_done {row['after_sim_done']} "
                  f"wall {row['wall']:.1f} s load {row['load']:.2f}", flush=True)
    verdicts = collections.Counter(r["verdict"] for r in rows)
    want = sum(expected.values()) * len(rows)
    got = sum(min(r["startup"].get(f"{s} {k}", 0), n) for r in rows
              for (s, k), n in expected.items())
    figures = [
        Figure("clean_runs", f"{args.mode} runs of {args.scenario.name} ending clean",
               float(verdicts["clean"]), "runs", target=float(len(rows)), better="higher",
               note=", ".join(f"{v}: {n}" for v, n in sorted(verdicts.items()))),
        Figure("startup_recorded", "start-up events recorded (plan_ready, coupling_limits)",
               100.0 * got / want if want else 100.0, "%", target=100.0, better="higher",
               note=f"{got} of {want}"),
    ]
    report("record_bench", figures, args.out, load_before=load_before,
           extra={"runs": rows, "scenario": str(args.scenario), "mode": args.mode})
    return 0 if all(f.met for f in figures) else 1


if __name__ == "__main__":
    sys.exit(main())
