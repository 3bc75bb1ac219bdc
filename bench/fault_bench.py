"""Benchmark of injected faults: detection, stop and recovery times.

    .venv/bin/python bench/fault_bench.py [--runs N] [--only cut,freeze,restart] [--out FILE]

Each fault kind is injected ``--runs`` times (≥ 3) into the two-robot system-test fleet
(``tests/system/two_robots.toml``) in realtime for 10 s of sim time, at t = 3 s on robot 2 (STL,
100 Hz), with the fault tests' knobs: zenoh lease 500 ms on every process, the simulator's
watchdog 0.15 s and LTL robots at 10 Hz (``tests/system/test_system_link_faults.py`` says why):

* **cut** — ``cut:robot2@3+2`` on one namespace host
  (``tlfleet.coordinator.run_hosts.run_on_hosts``; root);
* **partition** — ``partition:robot2,sim@3+2``: only robot 2's agent and the simulator lose each
  other; both keep the router (the peer layout of ``tlfleet.coordinator.launch.netns_hosts``; root);
* **freeze** — ``freeze:robot2@3+2`` (SIGSTOP/SIGCONT), processes on loopback;
* **restart** — ``restart:robot2@3`` (SIGKILL, same argv again), processes on loopback.

Figures per kind, medians over the runs (from ``events.jsonl`` and ``trajectory.csv``):

* **detection** [s wall]: the coordinator's first ``link_lost`` / ``process_died`` about the
  target after ``fault_start`` (both carry the wall time); for a partition, which leaves every
  process connected to the coordinator, the agent's own ``stale_mocap`` report (its last frame's
  sim time plus the silence it measured, minus the fault's start: sim ≈ wall in realtime);
* **stopped** [s sim]: the watchdog stop of robot 2 minus the sim time of its last command;
* **recovery** [s sim ≈ wall in realtime]: the first ``link_restored`` / ``process_recovered``
  after ``fault_end``, minus the fault end;
* **frames lost**: rows missing from ``trajectory.csv`` (gaps > 1.5 mocap periods);
* **commands lost**: the commands the agents say they published (``agent_stats``) minus those
  the simulator received (``sim_stats``), and **commands ignored** as too old by the simulator;
  not countable for a restart (the killed process's counters die with it);
* **contacts** (robot–robot) and **corrupted files**
  (``tlfleet.coordinator.record.rundir.read_run(strict=True)`` failing), summed over the runs.

Targets: detection ≤ 1 s, stopped ≤ 0.2 s, recovery ≤ 1 s, 0 contacts, 0 corrupted.
Nothing here is CPU-bound: the figures are wall/sim times of a realtime fleet on a shared 2-core
machine, so read them as orders of magnitude; the CPU time of the children is reported beside.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from common import RESULTS, Figure, load_average, report  # noqa: E402
from tlfleet.agent.model.faults import parse_fault  # noqa: E402
from tlfleet.coordinator.live.supervisor import SupervisorConfig  # noqa: E402
from tlfleet.coordinator.record import rundir  # noqa: E402
from tlfleet.coordinator.run import RunConfig, run_fleet  # noqa: E402
from tlfleet.coordinator.run_hosts import run_on_hosts  # noqa: E402

TWO = ROOT / "tests" / "system" / "two_robots.toml"
LEASE_MS = 500
WATCHDOG = 0.15
DURATION = 10.0
SPECS = {"cut": "cut:robot2@3+2", "partition": "partition:robot2,sim@3+2",
         "freeze": "freeze:robot2@3+2", "restart": "restart:robot2@3"}
ON_HOSTS = ("cut", "partition")  # faults that drop links: namespace hosts, root


def fast_scenario(out: Path) -> Path:
    text = TWO.read_text() + "\n[ltl]\ncontrol_rate = 10.0\n"
    out.write_text(text.replace("[sim]\n", f"[sim]\nwatchdog = {WATCHDOG}\n", 1))
    return out


def events(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines()
            if line.strip()]


def one_run(kind: str, scenario: Path, run_dir: Path) -> dict[str, Any]:
    fault = parse_fault(SPECS[kind])
    if kind in ON_HOSTS:
        done = run_on_hosts(scenario, 1, out=run_dir, mode="realtime", lease_ms=LEASE_MS,
                            faults=(fault,), capture=True,
                            supervise_args=["--duration", str(DURATION), "--no-rrd",
                                            "--no-report", "--quiet"],
                            sim_args=["--duration", str(DURATION)])
        code = done.returncode
    else:
        result = run_fleet(RunConfig(scenario, mode="realtime", out=run_dir, duration=DURATION,
                                     lease_ms=LEASE_MS, faults=(fault,), report=False,
                                     rrd=False, supervisor=SupervisorConfig(wall_timeout=120)))
        code = result.verdict.exit_code
    return measure(run_dir, code)


def measure(run_dir: Path, code: int) -> dict[str, Any]:
    evs = events(run_dir)
    start = next(e for e in evs if e["kind"] == "fault_start")
    end = next(e for e in evs if e["kind"] == "fault_end")
    target = start["data"]["targets"][0]
    robot = int(target.split("-")[1])
    seen = next((e for e in evs if e["kind"] in ("link_lost", "process_died")
                 and e["data"].get("process") == target), None)
    detection = seen["data"]["wall"] - start["data"]["wall"] if seen else math.inf
    if start["data"]["kind"] == "partition":
        seen = next((e for e in evs if e["kind"] == "stale_mocap"
                     and e["source"] == f"agent/{robot}" and e["t"] >= start["t"] - 1.0), None)
        detection = (seen["t"] + seen["data"]["silence"] - start["t"]) if seen else math.inf
    stops = [e for e in evs if e["kind"] == "watchdog_stop" and e["data"]["robot"] == robot
             and start["t"] - 0.2 <= e["t"] <= max(end["t"], start["t"]) + 1.0]
    stopped = (stops[0]["t"] - stops[0]["data"]["last_command_t"]) if stops else math.inf
    back = next((e for e in evs if e["t"] >= end["t"] and (
        (e["kind"] in ("link_restored", "process_recovered")
         and e["data"].get("process") == target)
        or (start["data"]["kind"] == "partition" and e["kind"] == "resumed"
            and e["source"] == f"agent/{robot}"))), None)
    recovery = back["t"] - end["t"] if back else math.inf
    corrupted = 0
    try:
        files = rundir.read_run(run_dir, strict=True)
        t = files.trajectory.t if files.trajectory is not None else np.array([])
    except Exception:  # any failure to read is a corrupted file
        corrupted, t = 1, np.array([])
    period = 0.01
    steps = np.diff(t)
    lost = int(sum(round(s / period) - 1 for s in steps if s > 1.5 * period))
    contacts = sum(1 for e in evs if e["kind"] == "contact"
                   and "wall" not in (e["data"].get("a"), e["data"].get("b")))
    sent = sum(e["data"]["commands"] for e in evs if e["kind"] == "agent_stats")
    sim = next((e["data"] for e in evs if e["kind"] == "sim_stats"), {})
    commands_lost = (math.nan if start["data"]["kind"] == "restart" or "commands" not in sim
                     else float(sent - sim["commands"]))
    return {"exit_code": code, "detection": detection, "stopped": stopped,
            "recovery": recovery, "frames_lost": lost, "contacts": contacts,
            "corrupted": corrupted, "detected_as": seen["kind"] if seen else None,
            "commands_lost": commands_lost,
            "commands_ignored": float(sim.get("stale_commands", math.nan))}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--only", default=",".join(SPECS))
    parser.add_argument("--out", type=Path, default=RESULTS / "fault_bench.json")
    args = parser.parse_args()
    kinds = [k for k in args.only.split(",") if k]
    for kind in [k for k in kinds if k in ON_HOSTS and os.geteuid() != 0]:
        print(f"fault_bench: {kind} needs root (namespace hosts): skipped", file=sys.stderr)
        kinds.remove(kind)
    load_before = load_average()
    runs: dict[str, list[dict[str, Any]]] = {}
    figures: list[Figure] = []
    with tempfile.TemporaryDirectory(prefix="fault_bench-") as tmp:
        scenario = fast_scenario(Path(tmp) / "two_robots.toml")
        for kind in kinds:
            cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            wall0 = time.perf_counter()
            runs[kind] = [one_run(kind, scenario, Path(tmp) / f"{kind}-{n}")
                          for n in range(max(3, args.runs))]
            cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime) / len(runs[kind])
            wall = (time.perf_counter() - wall0) / len(runs[kind])
            rows = runs[kind]

            def med(key: str, rows=rows) -> float:
                return statistics.median(r[key] for r in rows)

            spec = SPECS[kind]
            figures += [
                Figure(f"{kind}_detection_s", f"{spec}: detection (coordinator) [wall]",
                       med("detection"), "s", target=1.0),
                Figure(f"{kind}_stopped_s", f"{spec}: robot stopped after its last command",
                       med("stopped"), "s", target=0.2),
                Figure(f"{kind}_recovery_s", f"{spec}: recovery after the restore",
                       med("recovery"), "s", target=1.0),
                Figure(f"{kind}_frames_lost", f"{spec}: trajectory rows lost (median)",
                       med("frames_lost"), "rows"),
                Figure(f"{kind}_commands_lost", f"{spec}: commands lost (median)",
                       med("commands_lost"), "commands"),
                Figure(f"{kind}_commands_ignored", f"{spec}: commands ignored as too old "
                       "(median)", med("commands_ignored"), "commands"),
                Figure(f"{kind}_contacts", f"{spec}: robot-robot contacts (sum)",
                       float(sum(r["contacts"] for r in rows)), "", target=0.0),
                Figure(f"{kind}_corrupted", f"{spec}: corrupted run directories (sum)",
                       float(sum(r["corrupted"] for r in rows)), "", target=0.0),
                Figure(f"{kind}_run_cpu_s", f"{spec}: one run, CPU of the children",
                       cpu, "s", wall=wall),
            ]
    report("fault_bench", figures, args.out, load_before=load_before,
           extra={"runs": runs, "lease_ms": LEASE_MS, "watchdog": WATCHDOG,
                  "duration": DURATION, "specs": SPECS})
    return 0


if __name__ == "__main__":
    sys.exit(main())
