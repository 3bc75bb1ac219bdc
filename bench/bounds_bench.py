"""Bounded resources: what hostile or merely large inputs cost, and whether a long run grows.

    .venv/bin/python bench/bounds_bench.py [--quick] [--soak-seconds S]

* **Recurrences**: ``G F p1 & … & G F pn`` translated for n = 8, 16, 32, 64 — median CPU (3 runs)
  and the automaton's states; targets: n = 64 in ≤ 1 s CPU with ≤ n + 1 states
  (``tlfleet.agent.ltl.recurrence``).
* **Long conjunctions**: ``a & a & … & a`` with n = 1 000 and 16 000 operands, CPU per operand;
  target: the per-operand cost at 16 000 at most twice that at 1 000 (linear, not quadratic).
* **Simulator memory**: Scenario 2 in realtime for ``--soak-seconds`` (600 by default; 60 with
  ``--quick``) under ``tlfleet run``; the simulator's RSS sampled every 5 s from /proc; target:
  ≤ 5 MB growth between the end of the first minute (warm-up: imports, caches) and the end (a
  quick run measures from 20 s on and says so).

CPU beside wall and the load average as every benchmark (``bench/common.py``); JSON in
``bench/results/bounds_bench.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import RESULTS, ROOT, Figure, load_average, report, time_calls

SCENARIO2 = ROOT / "scenarios" / "scenario2.toml"


def recurrences(n: int) -> str:
    return " & ".join(f"G F p{i}" for i in range(1, n + 1))


def recurrence_figures() -> list[Figure]:
    from tlfleet.agent.ltl.buchi import translate

    figures = []
    for n in (8, 16, 32, 64):
        formula = recurrences(n)
        timing = time_calls(lambda f=formula: translate(f), runs=3)
        states = translate(formula).num_states
        figures.append(Figure(f"gf{n}_cpu_s", f"translate G F p1 & … & G F p{n}", timing.cpu, "s",
                              target=1.0 if n == 64 else None, wall=timing.wall))
        figures.append(Figure(f"gf{n}_states", f"  its states (n + 1 = {n + 1})", states, "",
                              target=float(n + 1)))
    return figures


def conjunction_figures() -> list[Figure]:
    from tlfleet.agent.ltl.buchi import translate

    per_op = {}
    walls = {}
    for n in (1000, 16000):
        formula = " & ".join(["a"] * n)
        timing = time_calls(lambda f=formula: translate(f), runs=3)
        per_op[n], walls[n] = timing.cpu / n * 1e6, timing.wall / n * 1e6
    return [
        Figure("and1000_us", "a & … & a, 1 000 operands: per operand", per_op[1000], "µs",
               wall=walls[1000]),
        Figure("and16000_us", "a & … & a, 16 000 operands: per operand", per_op[16000], "µs",
               wall=walls[16000]),
        Figure("and_ratio", "  per-operand cost 16 000 / 1 000 (linear: ~1)",
               per_op[16000] / per_op[1000], "×", target=2.0),
    ]


def rss_kb(pid: int) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def sim_pid(run_dir: Path, marker: str, timeout: float = 60.0) -> int | None:
    """The pid of the run's simulator (found by its command line: the scenario copy's path)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                argv = (entry / "cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if b"sim" in argv and any(marker.encode() in a for a in argv):
                return int(entry.name)
        time.sleep(0.2)
    return None


def soak_figures(seconds: float, quick: bool) -> tuple[list[Figure], dict]:
    warm = 20.0 if quick else 60.0
    with tempfile.TemporaryDirectory(prefix="tlfleet-soak-") as tmp:
        scenario = Path(tmp) / "soak-scenario2.toml"
        scenario.write_text(SCENARIO2.read_text())
        run_dir = Path(tmp) / "run"
        proc = subprocess.Popen(
            [sys.executable, "-m", "tlfleet.cli", "run", str(scenario), "--realtime",
             "--duration", repr(seconds), "--out", str(run_dir), "--no-report", "--no-rrd", "-q"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=ROOT)
        samples: list[tuple[float, int]] = []
        cpu0 = time.process_time()
        try:
            pid = sim_pid(run_dir, str(scenario))
            started = time.monotonic()
            while pid is not None and proc.poll() is None:
                kb = rss_kb(pid)
                if kb is None:
                    break
                samples.append((time.monotonic() - started, kb))
                time.sleep(5.0)
            proc.wait(timeout=seconds + 300)
        finally:
            if proc.poll() is None:
                proc.kill()
        info = json.loads((run_dir / "run.json").read_text()) if (run_dir / "run.json").exists() \
            else {}
    after = [(t, kb) for t, kb in samples if t >= warm]
    growth = (after[-1][1] - after[0][1]) / 1024.0 if len(after) >= 2 else float("nan")
    peak = max((kb for _t, kb in samples), default=0) / 1024.0
    figures = [
        Figure("sim_rss_growth_mb", f"simulator RSS growth, t = {warm:g}–{seconds:g} s "
               f"(Scenario 2, realtime)", growth, "MB", target=5.0,
               note="quick: a short run, the target is for 600 s" if quick else ""),
        Figure("sim_rss_peak_mb", "  simulator RSS, peak", peak, "MB"),
    ]
    return figures, {"rss_samples_kb": samples, "soak_seconds": seconds,
                     "run_outcome": info.get("outcome"), "measure_cpu_s":
                     time.process_time() - cpu0, "median_rss_mb":
                     statistics.median(kb for _t, kb in samples) / 1024.0 if samples else None}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a 60 s soak instead of 600 s")
    parser.add_argument("--soak-seconds", type=float, default=None,
                        help="sim time of the realtime soak [s] (default 600; 60 with --quick)")
    parser.add_argument("--soak-only", action="store_true",
                        help="only the simulator's soak (e.g. to measure another checkout)")
    parser.add_argument("--out", type=Path, default=RESULTS / "bounds_bench.json")
    args = parser.parse_args()
    load_before = load_average()
    soak = args.soak_seconds or (60.0 if args.quick else 600.0)
    figures = [] if args.soak_only else recurrence_figures() + conjunction_figures()
    soaked, extra = soak_figures(soak, args.quick)
    report("bounds_bench", figures + soaked, args.out, load_before=load_before, extra=extra,
           quick=args.quick)
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
