"""STL robots on any map (docs/stl-saturation.md): the corpus, random tasks, the paper's scenarios.

    .venv/bin/python bench/stl_maps_bench.py [--quick] [--seeds 1-5] [--tasks 1000]
                                             [--out bench/results/stl_maps_bench.json]

* **corpus**: every scenario of ``scenarios/stl/`` run in lockstep (``tlfleet run``, real
  processes) at each seed, judged by ``tests/stl_corpus.py`` from the recorded trajectory and
  events: every feasible sub-task met (ρ^φ > 0), the infeasible ones within 0.05 of their best
  possible, robot–robot contacts, and wall/obstacle contact samples beyond 1 s;
* **random tasks**: single-robot reaches (F) and stays (G) of a disc, start, goal, radius and
  window drawn from a seeded generator so that the minimal-time bound leaves 10–40 % of the
  window to spare (docs/stl-saturation.md §1), each run on the simulator's physics in one
  process (``tests/stl_world_harness.py``: velocity tracking with acceleration limits, lockstep
  timing); the share met and the median number of repairs;
* **paper**: Scenarios 1–3 as their files say (the published design) in lockstep, with the
  report's verdicts (Scenario 1: every paper bound met; Scenario 2: ρ ≥ −0.2; Scenario 3: the
  formation held ≥ 90 % of its window), and, for comparison only, with tlfleet's defaults;
* **step**: the STL control step's CPU with obstacles in range (``bench/stl_bench.py``).

Prints the goal table with met / not met (CPU beside wall time, the load average) and writes the
JSON (``bench.common``). ``--quick``: seed 1, 100 random tasks, no defaults rows.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from stl_corpus import CORPUS_DIR, NAMES, judge  # noqa: E402
from stl_world_harness import run_in_world  # noqa: E402
from tlfleet.agent.scenario import load_scenario, parse_scenario  # noqa: E402
from tlfleet.coordinator.live.supervisor import SupervisorConfig  # noqa: E402
from tlfleet.coordinator.run import RunConfig, run_fleet  # noqa: E402

from bench.common import Figure, load_average, report  # noqa: E402
from bench.stl_bench import bench_step_with_obstacles  # noqa: E402

SPEED = 0.2  # [m/s] the omni robots' default limit
PAPER_DEFAULTS = {"saturation_aware": True, "rho_opt_from_arena": True, "coupled_radii": True,
                  "wall_avoidance": True, "route_around": True, "lookahead": True,
                  "hold_f_above_r": False, "complete_f_on_satisfaction": True,
                  "complete_f_at_goal": True}


def _seeds(text: str) -> list[int]:
    if "-" in text:
        lo, hi = text.split("-")
        return list(range(int(lo), int(hi) + 1))
    return [int(s) for s in text.split(",")]


def lockstep(path: Path, out: Path, seed: int, *, report_files: bool = False,
             code: Path | None = None) -> bool:
    """One lockstep ``tlfleet run``; True when it ended clean. ``code``: a directory holding
    another tree of the package as ``tlfleet/`` (``--before``), run in a subprocess with it first
    on the path."""
    if code is not None:
        argv = [sys.executable, "-m", "tlfleet.cli", "run", str(path), "--lockstep", "--out",
                str(out), "--seed", str(seed), "--no-rrd", "--quiet", "--no-figures"]
        if not report_files:
            argv.append("--no-report")
        env = {**os.environ, "PYTHONPATH": str(code)}
        done = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=1800,
                              cwd=tempfile.gettempdir(), check=False)
        return done.returncode == 0
    supervisor = SupervisorConfig(ready_timeout=60.0, wall_timeout=900.0)
    return run_fleet(RunConfig(path, mode="lockstep", out=out, seed=seed, supervisor=supervisor,
                               report=report_files, figures=False, rrd=False)).clean


def bench_corpus(seeds: list[int], work: Path, code: Path | None = None,
                 names: tuple[str, ...] = NAMES) -> dict:
    feasible = met = infeasible = close = contacts = wall_beyond = runs = 0
    repairs = []
    rows = []
    for name in names:
        for seed in seeds:
            out = work / f"{name}-{seed}"
            clean = lockstep(CORPUS_DIR / f"{name}.toml", out, seed, code=code)
            runs += 1
            j = judge(name, out)
            for s in j.subtasks:
                if s.best is None:
                    feasible += 1
                    met += s.ok
                else:
                    infeasible += 1
                    close += s.ok
            contacts += j.robot_contacts
            wall_beyond += j.wall_beyond_1s
            repairs.append(j.repairs)
            rows.append({"scenario": name, "seed": seed, "clean": clean,
                         "subtasks": [(s.robot, s.index, round(s.rho, 4), s.best, s.ok)
                                      for s in j.subtasks],
                         "robot_contacts": j.robot_contacts,
                         "wall_contact_samples": j.wall_contact_samples,
                         "wall_beyond_1s": j.wall_beyond_1s, "repairs": j.repairs})
            bad = [f"r{s.robot}.{s.index + 1} {s.rho:+.3f}" for s in j.subtasks if not s.ok]
            print(f"  {name:18} seed {seed}: {'ok' if j.ok else 'NOT ok'} "
                  f"{' '.join(bad)} contacts {j.robot_contacts} wall>1s {j.wall_beyond_1s} "
                  f"repairs {j.repairs}", flush=True)
    return {"feasible": feasible, "met": met, "infeasible": infeasible, "close": close,
            "robot_contacts": contacts, "wall_beyond_1s": wall_beyond, "runs": runs,
            "median_repairs": statistics.median(repairs) if repairs else math.nan, "rows": rows}


def random_task(rng: np.random.Generator) -> tuple[dict, float, tuple]:
    """One feasible reach or stay with 10–40 % of its window to spare (module docstring):
    (scenario table, the share of the window the minimal-time bound needs, the disc)."""
    while True:
        kind = str(rng.choice(["G", "F"]))
        radius = float(rng.uniform(0.1, 0.5))
        start = rng.uniform(-3.0, 3.0, 2)
        goal = rng.uniform(-3.0, 3.0, 2)
        need = (float(np.linalg.norm(goal - start)) - radius) / SPEED
        if need >= 1.0:
            break
    share = float(rng.uniform(1.0 / 1.4, 1.0 / 1.1))
    due = math.floor(need / share * 100.0) / 100.0
    if kind == "G":
        a, b = due, due + round(float(rng.uniform(0.5, 8.0)), 2)
    else:
        a, b = round(float(rng.uniform(0.0, 1.0)) * due, 2), due
    text = f"{kind}[{a:.2f},{b:.2f}] (dist(p1, [{goal[0]:.4f}, {goal[1]:.4f}]) <= {radius:.4f})"
    data = {"name": "random", "duration": b + 0.05, "sim": {"seed": 1},
            "robots": [{"id": 1, "kind": "omni", "pose": [float(start[0]), float(start[1]), 0.0],
                        "stl": [text]}]}
    return data, need / (a if kind == "G" else b), (kind, a, b, goal, radius)


def bench_random(count: int, seed: int = 2026) -> dict:
    rng = np.random.default_rng(seed)
    met, repairs, shares, failures = 0, [], [], []
    c0, w0 = time.thread_time(), time.perf_counter()
    for n in range(count):
        data, share, (kind, a, b, goal, radius) = random_task(rng)
        run = run_in_world(parse_scenario(data))
        z = run.states[1][:, :2]
        rho = radius - np.hypot(z[:, 0] - goal[0], z[:, 1] - goal[1])
        window = (run.t >= a - 1e-9) & (run.t <= b + 1e-9)
        value = float(rho[window].min() if kind == "G" else rho[window].max())
        met += value > 0.0
        repairs.append(run.repairs)
        shares.append(share)
        if value <= 0.0:
            robot = data["robots"][0]
            failures.append({"task": robot["stl"][0], "start": robot["pose"], "rho": value,
                             "repairs": run.repairs})
        if (n + 1) % 100 == 0:
            print(f"  random tasks: {n + 1}/{count}, met {met}", flush=True)
    return {"count": count, "met": met, "median_repairs": statistics.median(repairs),
            "mean_repairs": statistics.mean(repairs), "share_range": (min(shares), max(shares)),
            "failures": failures[:20], "cpu_s": time.thread_time() - c0,
            "wall_s": time.perf_counter() - w0}


def _paper_figures(run_dir: Path, number: int) -> tuple[bool, str]:
    import json

    data = json.loads((run_dir / "report.json").read_text())
    subtasks = [s for robot in data["stl"].values() for s in robot["subtasks"]]
    if number == 1:
        ok = all(s["paper"]["met"] for s in subtasks if s.get("paper"))
        text = " ".join(f"{s['label']} {s['robustness']:+.3f}" for s in subtasks)
    elif number == 2:
        ok = all(s["robustness"] >= -0.2 for s in subtasks)
        text = " ".join(f"{s['label']} {s['robustness']:+.3f}" for s in subtasks)
    else:
        held = [v["held"] for robot in data["verdicts"]["subtasks"].values() for v in robot]
        ok = min(held) >= 0.9
        text = "held " + " ".join(f"{h:.0%}" for h in held)
    return ok, text


def with_defaults(text: str) -> str:
    """A paper scenario's TOML with tlfleet's defaults in place of its pinned [stl] switches."""
    lines = text.splitlines()
    seen = set()
    for k, line in enumerate(lines):
        key = line.split("=")[0].strip()
        if key in PAPER_DEFAULTS:
            lines[k] = f"{key} = {str(PAPER_DEFAULTS[key]).lower()}"
            seen.add(key)
    at = next((k + 1 for k, line in enumerate(lines) if line.startswith("[stl]")), None)
    missing = [f"{k} = {str(v).lower()}" for k, v in PAPER_DEFAULTS.items() if k not in seen]
    if at is None:
        lines += ["[stl]", *missing]
    else:
        lines[at:at] = missing
    return "\n".join(lines) + "\n"


def bench_paper(work: Path, defaults: bool, code: Path | None = None) -> dict:
    out = {}
    files = (code / "tlfleet" / "scenarios") if code is not None else ROOT / "scenarios"
    for number in (1, 2, 3):
        path = files / f"scenario{number}.toml"
        for variant in (("file", "defaults") if defaults else ("file",)):
            target = path
            if variant == "defaults":
                target = work / f"scenario{number}-defaults.toml"
                target.write_text(with_defaults(path.read_text()))
            run_dir = work / f"paper{number}-{variant}"
            lockstep(target, run_dir, load_scenario(path).sim.seed, report_files=True, code=code)
            ok, text = _paper_figures(run_dir, number)
            out[f"s{number}_{variant}"] = {"ok": ok, "figures": text}
            print(f"  scenario {number} ({variant}): {'met' if ok else 'NOT met'}: {text}",
                  flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="seed 1, 100 random tasks, no defaults rows")
    parser.add_argument("--seeds", default="1-5", help="corpus seeds, e.g. 1-5 or 1,3")
    parser.add_argument("--tasks", type=int, default=1000, help="random tasks")
    parser.add_argument("--skip", default="", help="comma list of parts to skip: corpus, "
                                                   "random, paper, step")
    parser.add_argument("--scenarios", default=",".join(NAMES),
                        help="comma list of corpus scenarios (default: all)")
    parser.add_argument("--before", type=Path, default=None,
                        help="a directory holding another tree of the package as tlfleet/: its "
                             "fleets run the corpus and the paper's files (the judge is this "
                             "tree's); e.g. main before this work, for the before/after table")
    parser.add_argument("--out", type=Path,
                        default=ROOT / "bench" / "results" / "stl_maps_bench.json")
    args = parser.parse_args(argv)
    seeds = [1] if args.quick else _seeds(args.seeds)
    tasks = min(args.tasks, 100) if args.quick else args.tasks
    skip = set(filter(None, args.skip.split(",")))
    load_before = load_average()
    figures: list[Figure] = []
    extra: dict = {"seeds": seeds}
    with tempfile.TemporaryDirectory(prefix="stl-maps-") as tmp:
        work = Path(tmp)
        if "corpus" not in skip:
            print(f"corpus: scenarios {args.scenarios} × seeds {seeds} (lockstep)", flush=True)
            c = bench_corpus(seeds, work, args.before, tuple(args.scenarios.split(",")))
            extra["corpus"] = c
            figures += [
                Figure("corpus_feasible_met", f"corpus: feasible sub-tasks met (of "
                       f"{c['feasible']}, {c['runs']} runs)", c["met"] / max(c["feasible"], 1),
                       "share", 1.0, better="higher"),
                Figure("corpus_infeasible_close", f"corpus: infeasible sub-tasks within 0.05 of "
                       f"their best (of {c['infeasible']})", c["close"] / max(c["infeasible"], 1),
                       "share", 1.0, better="higher"),
                Figure("corpus_robot_contacts", "corpus: robot-robot contacts",
                       c["robot_contacts"], "count", 0.0),
                Figure("corpus_wall_beyond_1s", "corpus: wall/obstacle contact samples beyond "
                       "1 s", c["wall_beyond_1s"], "count", 0.0),
                Figure("corpus_median_repairs", "corpus: median repairs a run",
                       c["median_repairs"], "count"),
            ]
        if "random" not in skip:
            print(f"random tasks: {tasks} (simulator physics, in process)", flush=True)
            r = bench_random(tasks)
            extra["random"] = r
            figures += [
                Figure("random_met", f"{r['count']} random feasible reach/stay tasks met",
                       r["met"] / r["count"], "share", 0.99, better="higher"),
                Figure("random_median_repairs", "random tasks: median repairs",
                       r["median_repairs"], "count", 0.0),
            ]
        if "step" not in skip:
            cpu, wall = bench_step_with_obstacles(7, 300 if args.quick else 5000)
            figures.append(Figure("step_obstacles_us", "STL control step, 3-robot task, 10 "
                                  "neighbours, obstacles in range", cpu, "µs", 35.0, wall=wall))
        if "paper" not in skip:
            print("paper scenarios (lockstep)", flush=True)
            p = bench_paper(work, defaults=not args.quick and args.before is None,
                            code=args.before)
            extra["paper"] = p
            for key, value in p.items():
                target = 1.0 if key.endswith("_file") else None
                figures.append(Figure(f"paper_{key}", f"Scenario {key[1]} ({key[3:]}): "
                                      f"{value['figures']}", float(value["ok"]), "met", target,
                                      better="higher"))
    report("stl_maps_bench", figures, args.out, load_before=load_before, quick=args.quick,
           extra=extra)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
