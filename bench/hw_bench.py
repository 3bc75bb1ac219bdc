"""The hardware bridge's goals (docs/hardware.md), against rclpy fake robots in isolated network
namespaces (tests/ros: ros_harness, ros_case, fake_robots). Needs root and the tlfleet[ros2] extra.

    .venv/bin/python bench/hw_bench.py [--trials 20] [--cpu-runs 3] [--quick | --cpu]

1. **Scenario 1 over the bridge**: ``pytest tests/ros`` runs the acceptance test (the paper's
   bounds, LTL visits, 0 contacts through ``tlfleet run --hardware``) with every other ROS test;
   its wall time plus the install of the extra on top of the suite's own dependencies
   (:func:`ci_time`) is the **extra CI time**.
2. **Frame → command on the robot's topic, 5 robots at 100 Hz**: Scenario 1's five robots behind
   the bridge, a stand-in agent answering every tick frame at once for every robot with a command
   whose angular rate codes the frame's seq; latency = the fake robot's reception − the frame's
   arrival at the agent (both CLOCK_MONOTONIC), i.e. the agent's answer, two zenoh hops, the
   bridge's checks and safety rules and the DDS hop; **lost** = answered seqs that never reached
   the robot (reliable QoS). The bridge's **CPU** over the same window (from /proc), the median
   of ``--cpu-runs`` runs, each beside the **floor**: a bare rclpy node on the same five pose
   topics (``bench/hw_floor_node.py``) in three forms, run between the bridge's runs — rclpy's
   ``SingleThreadedExecutor`` with a callback per pose; the bridge's way (taken serialized every
   10 ms, the newest deserialized); that plus 500 twists a second published, the bridge's ROS
   traffic without zenoh, frames or safety rules.
3. **Zero after SIGTERM / agent death / lost body**: ``--trials`` missions each; the time from the
   SIGTERM, from the agent's last command (minus nothing: the scenario's watchdog is 0.3 s) and
   from the body's last pose to the robot's first zero.

The machine is shared: realtime figures carry its load (printed); the cases run under SCHED_FIFO
as ``tlfleet run``'s fleets do.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "ros"))
sys.path.insert(0, str(ROOT / "bench"))

from common import RESULTS, Figure, load_average, report  # noqa: E402
from ros_case import seq_of  # noqa: E402
from ros_harness import run_case, unique_domain  # noqa: E402

FLEET = str(ROOT / "tests" / "ros" / "four_robots.toml")
FLOOR_NODE = str(ROOT / "bench" / "hw_floor_node.py")
FLOORS = {"executor": "a bare rclpy subscriber (SingleThreadedExecutor), 500 poses/s",
          "poll": "a bare node taking the 500 poses/s as the bridge does (every 10 ms)",
          "poll_answer": "that node publishing 500 twists/s besides"}
SCENARIO1 = str(ROOT / "scenarios" / "scenario1.toml")
GOALS = {"1": [-1.0, -1.0], "2": [1.5, -1.0], "3": [-1.0, 1.0], "4": [1.5, 1.0]}
AGE = ["--max-command-age", "0.5"]


def is_zero(row: dict) -> bool:
    return all(v == 0.0 for v in row["u"])


def latency_case(tmp: Path, seconds: float) -> dict:
    case = {"kind": "bridge", "scenario": SCENARIO1, "domain_id": unique_domain(), "args": AGE,
            "steps": [{"do": "start"}, {"do": "sleep", "s": 1.0},
                      {"do": "echo", "s": seconds}, {"do": "sigterm"},
                      {"do": "wait_exit", "s": 15}]}
    result = run_case(case, tmp, timeout=120)
    echoed = {int(k): v for k, v in result["echoed"].items()}
    first_echo = min(echoed) if echoed else 0
    latencies, lost, sent = [], 0, 0
    by_robot: dict[str, dict[int, list[float]]] = {}
    for row in result["received"]:
        if is_zero(row):
            continue
        by_robot.setdefault(row["robot"], {}).setdefault(seq_of(row["u"][-1]), []).append(
            row["t"])
    for got in by_robot.values():
        for seq, t_frame in echoed.items():
            sent += 1
            # the first reception of this seq's code after its frame (codes repeat every
            # 1000 frames, 10 s; the keep-alive re-sends a command later)
            match = [t for t in got.get(seq % 1000, ()) if t_frame <= t < t_frame + 5.0]
            if not match:
                lost += 1
                continue
            latencies.append(min(match) - t_frame)
    marks = {do: (t, cpu) for do, t, cpu in result["cpu_at"]}
    t0, cpu0 = marks["echo"][0], marks["echo"][1].get("bridge", float("nan"))
    t1, cpu1 = marks["sigterm"][0], marks["sigterm"][1].get("bridge", float("nan"))
    return {"latencies_ms": [1e3 * v for v in latencies], "sent": sent, "lost": lost,
            "robots": len(by_robot), "frames": len(echoed), "first_seq": first_echo,
            "bridge_cpu_share": (cpu1 - cpu0) / (t1 - t0), "window_s": t1 - t0}


def floor_case(tmp: Path, mode: str, seconds: float) -> float:
    """CPU share of a bare rclpy node (:data:`FLOORS`) beside Scenario 1's five fake robots."""
    case = {"kind": "probe", "scenario": SCENARIO1, "domain_id": unique_domain(),
            "argv": [sys.executable, FLOOR_NODE, mode], "warmup": 3.0, "window": seconds,
            "steps": []}
    return run_case(case, tmp, timeout=120)["probe_cpu_share"]


def stop_trial(tmp: Path) -> dict:
    """Agent death (robot 3 silent) then SIGTERM; returns the two delays [s]."""
    case = {"kind": "bridge", "scenario": FLEET, "domain_id": unique_domain(), "args": AGE,
            "steps": [{"do": "start"},
                      {"do": "stream", "s": 1.0, "rates": {"1": 5, "2": 5, "3": 100, "4": 100},
                       "goals": GOALS},
                      {"do": "stream", "s": 1.0, "rates": {"1": 5, "2": 5, "4": 100},
                       "goals": GOALS},
                      {"do": "sigterm"}, {"do": "wait_exit", "s": 15}]}
    result = run_case(case, tmp, timeout=90)
    silent, term = result["marks"]["stream"][1], result["marks"]["sigterm"][0]
    exited = result["marks"]["bridge_exit"][0]
    rows = result["received"]
    death = [r["t"] - silent for r in rows if r["robot"] == "r3" and is_zero(r)
             and r["t"] > silent]
    stops = []
    for robot in ("r1", "r2", "r4"):
        z = [r["t"] - term for r in rows if r["robot"] == robot and is_zero(r)
             and term <= r["t"] < exited]
        stops.append(min(z) if z else float("inf"))
    return {"death": min(death) if death else float("inf"), "sigterm": max(stops)}


def lost_trial(tmp: Path) -> float:
    case = {"kind": "bridge", "scenario": FLEET, "domain_id": unique_domain(), "args": AGE,
            "lab": {"lost_after": 0.2}, "robots": {"2": {"lose_after": 1.0}},
            "steps": [{"do": "start"},
                      {"do": "stream", "s": 2.0, "rates": {"1": 5, "2": 5, "3": 100, "4": 100},
                       "goals": GOALS},
                      {"do": "stop"}, {"do": "wait_exit", "s": 15}]}
    result = run_case(case, tmp, timeout=90)
    rows = result["received"]
    lost_at = min(r["t"] for r in rows if r["robot"] == "r2") + 1.0
    delays = []
    for robot in ("r1", "r2", "r3", "r4"):
        z = [r["t"] - lost_at for r in rows if r["robot"] == robot and is_zero(r)
             and r["t"] > lost_at]
        delays.append(min(z) if z else float("inf"))
    return max(delays)


def ci_time(tmp: Path) -> dict:
    """The extra CI time of the ROS part, as ``make test`` spends it: installing the extra on top
    of what the suite installs anyway (a fresh venv with tlfleet's dependencies and its test
    extra, untimed; then the ``ros2`` extra's pins, timed: the one pip call of
    ``.venv/.installed-ros2`` installs the same, the package itself being built once either way),
    and ``pytest tests/ros``. Wall and CPU (of the child processes) of each."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    pip = [str(venv / "bin" / "python"), "-m", "pip", "install", "--quiet"]
    subprocess.run([*pip, *project["dependencies"], *project["optional-dependencies"]["test"]],
                   check=True, capture_output=True)
    install = _timed([*pip, *project["optional-dependencies"]["ros2"]])
    tests = _timed([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                    str(ROOT / "tests" / "ros")])
    return {"install": install, "tests": tests}


def _timed(argv: list[str]) -> dict:
    """Run ``argv`` (in the repository); its wall and children's CPU time [s], outcome."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu0 = usage.ru_utime + usage.ru_stime
    start = time.perf_counter()
    proc = subprocess.run(argv, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - start
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    lines = proc.stdout.strip().splitlines()
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime - cpu0,
            "passed": proc.returncode == 0, "last_line": lines[-1] if lines else proc.stderr[-300:]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--seconds", type=float, default=10.0, help="latency window [s]")
    parser.add_argument("--cpu-runs", type=int, default=3,
                        help="latency/CPU runs, each followed by the floor nodes' (medians)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--quick", action="store_true",
                      help="3 trials, 1 CPU run, no fresh install, no acceptance run")
    mode.add_argument("--cpu", action="store_true",
                      help="only the latency/CPU runs and the floor (no trials, no CI time)")
    args = parser.parse_args()
    trials = 0 if args.cpu else 3 if args.quick else args.trials
    cpu_runs = 1 if args.quick else max(1, args.cpu_runs)
    load_before = load_average()
    figures: list[Figure] = []
    extra: dict = {}
    with tempfile.TemporaryDirectory(prefix="hw_bench-") as tmp_name:
        tmp = Path(tmp_name)
        if not (args.quick or args.cpu):
            ci = ci_time(tmp)
            extra["ci"] = ci
            install, tests = ci["install"], ci["tests"]
            figures.append(Figure("acceptance", "Scenario 1 over the bridge: tests/ros pass "
                                  "(same verdicts, 0 contacts)", float(tests["passed"]), "",
                                  target=1.0, better="higher", note=tests["last_line"]))
            figures.append(Figure("ci_time_s", "extra CI time: install the extra + tests/ros",
                                  install["wall"] + tests["wall"], "s", target=180.0,
                                  note=f"install {install['wall']:.1f} s wall "
                                       f"({install['cpu']:.1f} s CPU, pip cache as it is), "
                                       f"tests {tests['wall']:.1f} s wall "
                                       f"({tests['cpu']:.1f} s CPU)"))
        runs: list[dict] = []
        floors: dict[str, list[float]] = {m: [] for m in FLOORS}
        for k in range(cpu_runs):  # bridge and floors interleaved: the load drifts
            load = load_average()[0]
            lat = latency_case(tmp / f"latency{k}", args.seconds)
            lat["load_1min"] = load
            runs.append(lat)
            for m in FLOORS:
                floors[m].append(floor_case(tmp / f"floor{k}-{m}", m, args.seconds))
        ms = np.concatenate([np.asarray(r["latencies_ms"]) for r in runs])
        extra["latency"] = [{k: v for k, v in r.items() if k != "latencies_ms"} for r in runs]
        extra["floor_cpu_share"] = floors
        sent = sum(r["sent"] for r in runs)
        lost = sum(r["lost"] for r in runs)
        cpu = [100.0 * r["bridge_cpu_share"] for r in runs]
        loads = ", ".join(f"{r['load_1min']:.1f}" for r in runs)
        figures.append(Figure("latency_p50_ms", "frame -> command on the robot's topic, 5 "
                              "robots at 100 Hz: p50", float(np.percentile(ms, 50)), "ms"))
        figures.append(Figure("latency_p99_ms", "frame -> command on the robot's topic: p99",
                              float(np.percentile(ms, 99)), "ms", target=5.0,
                              note=f"{len(ms)} commands of {cpu_runs} runs x 5 robots"))
        figures.append(Figure("lost_pct", "commands lost on reliable QoS",
                              100.0 * lost / max(1, sent), "%", target=0.0))
        figures.append(Figure("bridge_cpu_pct", "bridge CPU, 5 robots at 100 Hz (median)",
                              float(np.median(cpu)), "% of a core", target=15.0,
                              note=f"runs {', '.join(f'{c:.1f}' for c in cpu)} at load "
                                   f"{loads}"))
        for m, label in FLOORS.items():
            values = [100.0 * v for v in floors[m]]
            figures.append(Figure(f"floor_{m}_cpu_pct", f"floor: {label} (median)",
                                  float(np.median(values)), "% of a core",
                                  note="runs " + ", ".join(f"{v:.1f}" for v in values)))
        deaths, terms, losts = [], [], []
        for k in range(trials):
            trial = stop_trial(tmp / f"stop{k}")
            deaths.append(trial["death"])
            terms.append(trial["sigterm"])
            losts.append(lost_trial(tmp / f"lost{k}"))
        extra["trials"] = {"death_s": deaths, "sigterm_s": terms, "lost_body_s": losts}
        for key, label, values, note in (
                ("sigterm", "zero received after SIGTERM, worst robot", terms, ""),
                ("death", "zero received after the agent's last command", deaths,
                 "the scenario's watchdog is 0.3 s"),
                ("lost", "zero to every robot after the body's last pose", losts,
                 "lost_after 0.2 s")):
            if not values:
                continue
            within = sum(1 for v in values if v <= 0.5)
            figures.append(Figure(f"{key}_within_pct", f"{label}: trials within 0.5 s",
                                  100.0 * within / len(values), "%", target=100.0,
                                  better="higher",
                                  note=f"median {np.median(values):.3f} s, worst "
                                       f"{max(values):.3f} s of {len(values)}; {note}"))
    name = "hw_bench_cpu" if args.cpu else "hw_bench"
    report(name, figures, RESULTS / f"{name}.json", load_before=load_before, extra=extra,
           quick=args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
