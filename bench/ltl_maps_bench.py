"""LTL robots on any map: the goal table of docs/ltl-navigation.md §7.

    python bench/ltl_maps_bench.py                       # everything: corpus seeds 1-5, 200 maps
    python bench/ltl_maps_bench.py --quick               # corpus seed 1, 30 maps, no baseline
    python bench/ltl_maps_bench.py --base-root /path/to/other/checkout   # step cost and maps
                                                         # of another tree beside this one's
    python bench/ltl_maps_bench.py --corpus-root /path/to/other/checkout --skip maps,step,paper
                                                         # the corpus driven by another tree

Five measurements, each a row of the goal table (printed with its target and met / not met;
JSON in ``bench/results/ltl_maps_bench.json``):

1. **The corpus** (``scenarios/ltl_maps/``, ``tests/ltl_corpus.py``): every file through
   ``tlfleet run --lockstep`` for each seed; per LTL robot the word recomputed from
   ``trajectory.csv`` and the task evaluated on it exactly (lasso evaluator), unplanned region
   entries, contacts (robot–robot and robot–wall) and standstills of 5 s or more while the task
   wants motion (a yield's wait ≤ 15 s is no standstill).
2. **Random maps**: ``--maps`` maps of random rectangles and discs with regions ``a``, ``b``,
   ``c`` (``c`` half the time on the line between ``a`` and ``b``) and the task
   ``G F a & G F b & G !c``, regenerated until the keep-out plan exists (every map is solvable
   under the rule). The LTL agent drives the robot on the closed-loop unicycle harness
   (``tests/nav_harness.py``, 100 Hz Euler, first-order velocity tracking): success when it has
   entered ``a`` and ``b`` within twice the optimal path's time at maximum speed (the optimal
   path: the keep-out plan's transitions until both are visited, ``RegionPaths`` lengths) and
   never entered ``c``; path efficiency = the length driven until then / that optimal length.
   With ``--base-root`` the same maps are driven by the other tree's agent (a child process of
   its interpreter), judged against the same optimum.
3. **LTL step cost**: ``bench/nav_bench.py``'s replay of Scenario 1's LTL agents (CPU per step,
   median), this tree against ``--base-root``'s, runs interleaved.
4. **Scenarios 1–3**: each once in lockstep: S1 every bound met, S2 robustness ≥ −0.2, S3 the
   formation held ≥ 90 % of its window, and every LTL robot's task met on its word.

CPU beside wall time and the load average are recorded; lockstep outcomes do not depend on the
load, timings do.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))  # the closed-loop harness and the corpus analysis

DEFAULT_OUTPUT = ROOT / "bench" / "results" / "ltl_maps_bench.json"
V_MAX = 0.3  # [m/s] the unicycles' default top speed (UnicycleLimits.max_v)
TIME_FACTOR = 2.0  # success: both regions within this × the optimal path's time at V_MAX


# ----------------------------------------------------------------------------- random maps

def random_map(rng: np.random.Generator, index: int) -> str:
    """The TOML text of one random map (module docstring, 2.), solvable under the keep-out
    rule; the caller checks that and draws again otherwise."""
    width, height = rng.uniform(6.0, 10.0), rng.uniform(5.0, 8.0)
    if rng.random() < 0.5:  # half of them with the origin at a corner
        xmin, ymin = 0.0, 0.0
    else:
        xmin, ymin = -width / 2, -height / 2
    xmax, ymax = xmin + width, ymin + height
    lines = [f'name = "map{index:03d}"', "duration = 600.0", "", "[arena]",
             f"xmin = {xmin:.3f}", f"xmax = {xmax:.3f}", f"ymin = {ymin:.3f}",
             f"ymax = {ymax:.3f}", ""]
    obstacles = []
    for _ in range(int(rng.integers(2, 6))):
        w, h = rng.uniform(0.2, 2.5), rng.uniform(0.2, 2.5)
        if rng.random() < 0.5:
            w, h = h, w
        x0, y0 = rng.uniform(xmin, xmax - w), rng.uniform(ymin, ymax - h)
        obstacles.append(("rect", (x0, y0, x0 + w, y0 + h)))
    for _ in range(int(rng.integers(1, 5))):
        r = rng.uniform(0.15, 0.6)
        obstacles.append(("disc", (rng.uniform(xmin + r, xmax - r),
                                   rng.uniform(ymin + r, ymax - r), r)))
    for kind, values in obstacles:
        lines.append("[[arena.obstacles]]")
        if kind == "rect":
            x0, y0, x1, y1 = values
            lines += ['shape = "rect"', f"xmin = {x0:.3f}", f"xmax = {x1:.3f}",
                      f"ymin = {y0:.3f}", f"ymax = {y1:.3f}", ""]
        else:
            cx, cy, r = values
            lines += ['shape = "disc"', f"center = [{cx:.3f}, {cy:.3f}]", f"radius = {r:.3f}",
                      ""]
    return "\n".join(lines)


def _clear_point(rng: np.random.Generator, arena, clearance: float, avoid=(), tries: int = 400):
    from tlfleet.agent.nav.grid import arena_clearance
    for _ in range(tries):
        p = np.array([rng.uniform(arena.xmin, arena.xmax), rng.uniform(arena.ymin, arena.ymax)])
        if float(arena_clearance(arena, p[None, :])[0]) < clearance:
            continue
        if all(math.dist(p, q) >= d for q, d in avoid):
            return p
    return None


def make_maps(count: int, seed: int, folder: Path) -> list[dict]:
    """``count`` solvable random maps written to ``folder``; each with its optimal path."""
    import tomllib

    from tlfleet.agent.ltl.transition_system import START
    from tlfleet.agent.model.scenario import Arena, DiscObstacle, RectObstacle
    from tlfleet.agent.nav.keep_out import RegionPaths
    from tlfleet.agent.policy.ltl import plan_on_map
    from tlfleet.agent.scenario import parse_scenario
    from tlfleet.bus.errors import UnsatisfiableTask

    rng = np.random.default_rng(seed)
    maps: list[dict] = []
    drawn = 0
    while len(maps) < count:
        drawn += 1
        text = random_map(rng, len(maps))
        a = tomllib.loads(text)["arena"]
        obs = []
        for o in a.get("obstacles", []):
            if o["shape"] == "rect":
                obs.append(RectObstacle(o["xmin"], o["ymin"], o["xmax"], o["ymax"]))
            else:
                obs.append(DiscObstacle(tuple(o["center"]), o["radius"]))
        arena = Arena(a["xmin"], a["xmax"], a["ymin"], a["ymax"], tuple(obs))
        pa = _clear_point(rng, arena, 0.6)
        pb = _clear_point(rng, arena, 0.6, [(pa, 2.5)]) if pa is not None else None
        if pb is None:
            continue
        r_c = float(rng.uniform(0.3, 0.6))
        if rng.random() < 0.5:  # on the straight line from a to b
            mid = (pa + pb) / 2 + rng.normal(0.0, 0.2, 2)
            pc = mid if all(math.dist(mid, q) >= 0.9 + r_c for q in (pa, pb)) else None
        else:
            pc = _clear_point(rng, arena, 0.3, [(pa, 0.9 + r_c), (pb, 0.9 + r_c)])
        if pc is None:
            continue
        start = _clear_point(rng, arena, 0.45,
                             [(pa, 0.8), (pb, 0.8), (pc, r_c + 0.6)])
        if start is None:
            continue
        heading = float(rng.uniform(-math.pi, math.pi))
        regions = "\n".join([
            "[[regions]]", 'name = "a"', f"center = [{pa[0]:.3f}, {pa[1]:.3f}]",
            "radius = 0.3", "",
            "[[regions]]", 'name = "b"', f"center = [{pb[0]:.3f}, {pb[1]:.3f}]",
            "radius = 0.3", "",
            "[[regions]]", 'name = "c"', f"center = [{pc[0]:.3f}, {pc[1]:.3f}]",
            f"radius = {r_c:.3f}", "",
            "[[robots]]", "id = 1", 'kind = "unicycle"',
            f"pose = [{start[0]:.3f}, {start[1]:.3f}, {heading:.4f}]",
            'ltl = "G F a & G F b & G !c"', ""])
        full = text + "\n" + regions
        try:
            scenario = parse_scenario(tomllib.loads(full), f"map{len(maps):03d}")
            paths = RegionPaths.from_scenario(scenario, 1)
            plan = plan_on_map(scenario, 1, paths=paths)
        except (UnsatisfiableTask, ValueError):
            continue
        seen, length, prev = set(), 0.0, None
        for name in (*plan.prefix, *plan.suffix, *plan.suffix):
            if name == START:
                prev = START
                continue
            if prev is not None and prev != name:
                origin = (float(start[0]), float(start[1])) if prev == START else prev
                length += paths.length(origin, name)
            prev = name
            seen.add(name)
            if {"a", "b"} <= seen:
                break
        path = folder / f"map{len(maps):03d}.toml"
        path.write_text(full)
        maps.append({"file": str(path), "optimal_length": length,
                     "c_on_line": bool(np.linalg.norm((pa + pb) / 2 - pc) < 1.0)})
    for entry in maps:
        entry["drawn"] = drawn
    return maps


def drive_maps(files: list[str]) -> list[dict]:
    """The LTL agent of this interpreter's tlfleet on each map file (harness, module docstring):
    the word with entry times and the length driven up to each entry; each map stops 5 s after
    both a and b were entered, or at its time budget (``$LTL_MAPS_BUDGET``, a JSON object of
    file → seconds)."""
    budgets = json.loads(os.environ.get("LTL_MAPS_BUDGET", "{}"))
    return [drive_one(file, float(budgets.get(file, 300.0))) for file in files]


def drive_one(file: str, budget: float) -> dict:
    """One map of :func:`drive_maps`."""
    from nav_harness import SimRobot, simulate
    from tlfleet.agent.policy.ltl import LtlAgent, LtlStepInput
    from tlfleet.agent.scenario import load_scenario

    scenario = load_scenario(file)
    agent = LtlAgent(scenario, 1)
    t0 = time.process_time()
    box = {"state": agent.initial_state(agent.plan())[0]}
    nobody = np.zeros((0, 4))

    def controller(t, i, poses):
        box["state"], step = agent.step(box["state"], LtlStepInput(t, tuple(poses[0]), nobody))
        box["state"] = agent.after_command(box["state"])
        return step.u

    entries: list[tuple[float, str, float]] = []
    seen: dict[str, float] = {}
    inside: set[str] = set()
    track = {"travelled": 0.0, "last": None}

    def watch(t, poses):
        # called at the control instants (5 Hz): entries are checked on the segment since the
        # last one, as the straight 6 cm between them
        p = poses[0, :2].copy()
        a = track["last"] if track["last"] is not None else p
        track["travelled"] += float(np.hypot(*(p - a)))
        track["last"] = p
        for region in scenario.regions:
            c = np.asarray(region.center, dtype=float)
            ab = p - a
            u = float(np.clip((c - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0))
            near = float(np.hypot(*(a + u * ab - c)))
            d = math.dist(p, region.center)
            if region.name not in inside and near <= region.radius:
                inside.add(region.name)
                entries.append((t, region.name, track["travelled"]))
                seen.setdefault(region.name, t)
            elif region.name in inside and d > region.radius + 0.05:
                inside.discard(region.name)
        return {"a", "b"} <= set(seen) and t > max(seen.values()) + 5.0

    robot = scenario.robot(1)
    result = simulate([SimRobot(tuple(robot.pose), robot.radius, robot.unicycle)],
                      [controller], budget, scenario.arena, stop=watch)
    return {"file": file, "entries": entries, "duration": result.duration,
            "contacts": len(result.contacts), "min_wall_gap": result.min_wall_gap,
            "cpu_s": time.process_time() - t0}


def judge(maps: list[dict], driven: list[dict]) -> dict:
    """Success and efficiency of every map (module docstring, 2.)."""
    rows = []
    for m, d in zip(maps, driven, strict=True):
        t_opt = m["optimal_length"] / V_MAX
        first = {}
        length_at = {}
        for t, name, travelled in d["entries"]:
            first.setdefault(name, t)
            length_at.setdefault(name, travelled)
        both = max(first.get("a", math.inf), first.get("b", math.inf))
        in_c = "c" in first
        ok = both <= TIME_FACTOR * t_opt and not in_c and d["contacts"] == 0
        efficiency = (max(length_at["a"], length_at["b"]) / m["optimal_length"]
                      if "a" in length_at and "b" in length_at and m["optimal_length"] > 0
                      else None)
        rows.append({"file": Path(m["file"]).name, "t_opt": t_opt, "t_both": both,
                     "entered_c": in_c, "contacts": d["contacts"], "success": ok,
                     "efficiency": efficiency, "c_on_line": m["c_on_line"]})
    n = len(rows)
    effs = [r["efficiency"] for r in rows if r["success"] and r["efficiency"] is not None]
    return {
        "maps": n,
        "success": sum(r["success"] for r in rows),
        "success_rate": sum(r["success"] for r in rows) / n if n else 0.0,
        "entered_c": sum(r["entered_c"] for r in rows),
        "contacts": sum(r["contacts"] for r in rows),
        "reached_both_in_time": sum(r["t_both"] <= TIME_FACTOR * r["t_opt"] for r in rows),
        "efficiency_median": statistics.median(effs) if effs else None,
        "efficiency_p90": float(np.percentile(effs, 90)) if effs else None,
        "failures": [r for r in rows if not r["success"]][:20],
    }


def run_maps(count: int, seed: int, base_root: Path | None) -> dict:
    with tempfile.TemporaryDirectory(prefix="ltl-maps-") as tmp:
        folder = Path(tmp)
        t0 = time.perf_counter()
        maps = make_maps(count, seed, folder)
        made = time.perf_counter() - t0
        budget = {m["file"]: TIME_FACTOR * m["optimal_length"] / V_MAX + 10.0 for m in maps}
        out = {"generated_s": made, "drawn": maps[0]["drawn"] if maps else 0}
        trees = [("this", None)] + ([("base", base_root)] if base_root else [])
        for label, root in trees:
            c0, w0 = time.process_time(), time.perf_counter()
            driven = _drive_in(root, [m["file"] for m in maps], budget)
            verdict = judge(maps, driven)
            verdict["wall_s"] = time.perf_counter() - w0
            verdict["cpu_s"] = sum(d["cpu_s"] for d in driven) if root else (
                time.process_time() - c0)
            out[label] = verdict
        return out


def _drive_in(root: Path | None, files: list[str], budget: dict) -> list[dict]:
    if root is None:
        os.environ["LTL_MAPS_BUDGET"] = json.dumps(budget)
        return drive_maps(files)
    python = root / ".venv" / "bin" / "python"
    env = {**os.environ, "LTL_MAPS_BUDGET": json.dumps(budget)}
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as handle:
        json.dump(files, handle)
    proc = subprocess.run([str(python), str(Path(__file__).resolve()), "--drive", handle.name],
                          capture_output=True, text=True, env=env, cwd=root, timeout=7200)
    if proc.returncode != 0:
        raise RuntimeError(f"the maps in {root} failed: {proc.stderr[-2000:]}")
    return json.loads(proc.stdout.splitlines()[-1])


# ----------------------------------------------------------------------------- the corpus

def run_corpus(seeds: list[int], out_dir: Path, root: Path | None = None,
               rejudge: bool = False) -> dict:
    """Every corpus file for every seed through ``tlfleet run --lockstep`` of this tree, or of
    ``root``'s (its ``.venv``), judged by this tree's ``tests/ltl_corpus.py``; ``rejudge``: the
    runs are in ``out_dir`` already (an earlier ``--runs-dir``), only judge them."""
    from ltl_corpus import CORPUS, analyse

    python = str(root / ".venv" / "bin" / "python") if root else sys.executable
    rows = []
    for case in CORPUS:
        for seed in seeds:
            run_dir = out_dir / f"{case.name}-s{seed}"
            t0 = time.perf_counter()
            proc = subprocess.CompletedProcess([], 0) if rejudge else subprocess.run(
                [python, "-m", "tlfleet.cli", "run", str(case.path), "--lockstep",
                 "--out", str(run_dir), "--quiet", "--no-rrd", "--no-figures",
                 "--seed", str(seed)], capture_output=True, text=True, timeout=1800,
                cwd=root or ROOT)
            wall = time.perf_counter() - t0
            try:
                outcome = analyse(run_dir)
            except (OSError, ValueError, KeyError) as exc:
                rows.append({"scenario": case.name, "seed": seed, "error": str(exc),
                             "exit": proc.returncode, "wall_s": wall})
                continue
            rows.append({
                "scenario": case.name, "seed": seed, "exit": proc.returncode, "wall_s": wall,
                "t_end": outcome.t_end,
                "robots": {r.robot: {"task": r.task, "met": r.met,
                                     "word": [n for _t, n in r.word],
                                     "unplanned": len(r.unplanned),
                                     "reported_unplanned": r.reported_unplanned,
                                     "standstills": r.standstills, "yields": r.yields,
                                     "cycles": r.cycles}
                           for r in outcome.robots.values()},
                "contacts": len(outcome.contacts),
            })
            print(f"  {case.name} seed {seed}: {wall:.0f} s wall, exit {proc.returncode}; "
                  + outcome.summary().split("\n", 1)[-1].replace("\n", ";"), flush=True)
    ok = [r for r in rows if "robots" in r]
    tasks = [rob for r in ok for rob in r["robots"].values()]
    return {
        "runs": len(rows), "errors": [r for r in rows if "error" in r],
        "tasks": len(tasks), "tasks_met": sum(t["met"] for t in tasks),
        "unplanned": sum(t["unplanned"] for t in tasks),
        "contacts": sum(r["contacts"] for r in ok),
        "standstills": sum(len(t["standstills"]) for t in tasks),
        "rows": rows,
    }


# ----------------------------------------------------------------------------- step cost

STEP_SNIPPET = """
import json, sys
sys.path.insert(0, 'bench'); sys.path.insert(0, 'tests')
from nav_bench import bench_ltl_agent_replay
r = bench_ltl_agent_replay(3, 60.0)
print(json.dumps(r['ltl_agent_step_scenario1']['cpu_median_ms']))
"""


def step_cost(base_root: Path | None, rounds: int) -> dict:
    trees = [("this", ROOT)] + ([("base", base_root)] if base_root else [])
    samples: dict[str, list[float]] = {label: [] for label, _ in trees}
    for _ in range(rounds):  # interleaved: the two trees see the same minutes of load
        for label, root in trees:
            python = root / ".venv" / "bin" / "python"
            proc = subprocess.run([str(python), "-c", STEP_SNIPPET], capture_output=True,
                                  text=True, cwd=root, timeout=1200)
            if proc.returncode != 0:
                raise RuntimeError(f"step cost in {root}: {proc.stderr[-1500:]}")
            samples[label].append(float(proc.stdout.split()[-1]))
    out = {label: {"cpu_median_ms": statistics.median(v), "runs": v}
           for label, v in samples.items()}
    if base_root:
        out["ratio"] = out["this"]["cpu_median_ms"] / out["base"]["cpu_median_ms"]
    return out


# ----------------------------------------------------------------------------- Scenarios 1-3

def paper_scenarios(out_dir: Path) -> dict:
    out = {}
    for k in (1, 2, 3):
        run_dir = out_dir / f"scenario{k}"
        proc = subprocess.run(
            [sys.executable, "-m", "tlfleet.cli", "run", str(ROOT / "scenarios" /
                                                            f"scenario{k}.toml"),
             "--lockstep", "--out", str(run_dir), "--quiet", "--no-rrd", "--no-figures"],
            capture_output=True, text=True, timeout=1800)
        report = json.loads((run_dir / "report.json").read_text())
        stl = report["stl"]
        if k == 1:
            met = [s["paper"]["met"] for r in stl.values() for s in r["subtasks"]]
            out["S1"] = {"bounds_met": sum(met), "bounds": len(met), "ok": all(met),
                         "exit": proc.returncode}
        elif k == 2:
            rho = [s["robustness"] for r in stl.values() for s in r["subtasks"]]
            out["S2"] = {"robustness": rho, "ok": min(rho) >= -0.2, "exit": proc.returncode}
        else:
            held = [s["held"] for v in report["verdicts"]["subtasks"].values() for s in v]
            out["S3"] = {"held": held, "ok": min(held) >= 0.9, "exit": proc.returncode}
        ltl = report.get("ltl", {})
        out[f"S{k}"]["ltl_met"] = [r["accepting"]["met"] for r in ltl.values()]
    return out


# ----------------------------------------------------------------------------- the table

def goal_rows(results: dict) -> list[tuple[str, str, str, bool | None]]:
    rows = []
    c = results.get("corpus")
    if c:
        rows.append(("corpus tasks met (lasso on the recomputed word)",
                     f"{c['tasks_met']}/{c['tasks']} over {c['runs']} runs", "all",
                     c["tasks_met"] == c["tasks"] and not c["errors"]))
        rows.append(("unplanned region entries, whole corpus", str(c["unplanned"]), "0",
                     c["unplanned"] == 0))
        rows.append(("contacts (robot-robot, robot-wall)", str(c["contacts"]), "0",
                     c["contacts"] == 0))
        rows.append(("standstill > 5 s while the task wants motion", str(c["standstills"]),
                     "0 (yield waits <= 15 s excepted)", c["standstills"] == 0))
    m = results.get("maps")
    if m:
        this = m["this"]
        rows.append(("random maps reaching a and b in 2x optimal time, never in c",
                     f"{100 * this['success_rate']:.1f} % of {this['maps']}", ">= 99 %",
                     this["success_rate"] >= 0.99))
        eff = this["efficiency_median"]
        rows.append(("path efficiency (driven / optimal), median",
                     "-" if eff is None else f"{eff:.3f}", "<= 1.15",
                     eff is not None and eff <= 1.15))
        if "base" in m:
            base = m["base"]
            eff_base = base["efficiency_median"]
            rows.append(("  (base tree: random maps success)",
                         f"{100 * base['success_rate']:.1f} %, in c {base['entered_c']}, "
                         f"eff. {'-' if eff_base is None else f'{eff_base:.3f}'}", "", None))
    s = results.get("step")
    if s:
        if "ratio" in s:
            rows.append(("LTL step cost (Scenario 1 replay, CPU median)",
                         f"{s['this']['cpu_median_ms']:.3f} ms vs {s['base']['cpu_median_ms']:.3f}"
                         f" ms ({100 * (s['ratio'] - 1):+.1f} %)", "<= +10 %",
                         s["ratio"] <= 1.10))
        else:
            rows.append(("LTL step cost (Scenario 1 replay, CPU median)",
                         f"{s['this']['cpu_median_ms']:.3f} ms", "<= +10 % (no base given)",
                         None))
    p = results.get("paper")
    if p:
        rows.append(("Scenario 1: every bound met", f"{p['S1']['bounds_met']}/"
                     f"{p['S1']['bounds']}", "all", p["S1"]["ok"]))
        rows.append(("Scenario 2: robustness >= -0.2",
                     ", ".join(f"{r:+.3f}" for r in p["S2"]["robustness"]), ">= -0.2",
                     p["S2"]["ok"]))
        rows.append(("Scenario 3: formation held",
                     ", ".join(f"{100 * h:.0f} %" for h in p["S3"]["held"]), ">= 90 %",
                     p["S3"]["ok"]))
        met = [m for k in ("S1", "S2", "S3") for m in p[k]["ltl_met"]]
        rows.append(("Scenarios 1-3: LTL tasks met (accepting on the word)",
                     f"{sum(met)}/{len(met)}", "all (as before)", all(met)))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="corpus at seed 1, 30 maps, 1 step-cost round")
    parser.add_argument("--seeds", default=None, help="corpus seeds, e.g. 1-5 (default 1-5)")
    parser.add_argument("--maps", type=int, default=None, help="random maps (default 200)")
    parser.add_argument("--map-seed", type=int, default=2024)
    parser.add_argument("--base-root", type=Path, default=None,
                        help="another checkout (with its .venv) to compare maps and step cost")
    parser.add_argument("--corpus-root", type=Path, default=None,
                        help="run the corpus with another checkout's tlfleet (its .venv), "
                             "e.g. to measure the table before a change")
    parser.add_argument("--rejudge", action="store_true",
                        help="judge the corpus runs already in --runs-dir instead of running "
                             "them again")
    parser.add_argument("--skip", default="", help="comma list of corpus,maps,step,paper")
    parser.add_argument("--runs-dir", type=Path, default=None,
                        help="keep the run directories here (default: a temporary directory)")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    parser.add_argument("--drive", help=argparse.SUPPRESS)  # child: drive the maps of a list
    args = parser.parse_args(argv)
    if args.drive:
        files = json.loads(Path(args.drive).read_text())
        print(json.dumps(drive_maps(files)))
        return 0
    skip = set(filter(None, args.skip.split(",")))
    if args.seeds:
        lo, _, hi = args.seeds.partition("-")
        seeds = list(range(int(lo), int(hi or lo) + 1))
    else:
        seeds = [1] if args.quick else [1, 2, 3, 4, 5]
    n_maps = args.maps if args.maps is not None else (30 if args.quick else 200)
    load_before = os.getloadavg()
    c0, w0 = time.process_time(), time.perf_counter()
    results: dict = {}
    with tempfile.TemporaryDirectory(prefix="ltl-maps-runs-") as tmp:
        runs = args.runs_dir or Path(tmp)
        if "corpus" not in skip:
            print(f"corpus, seeds {seeds}:", flush=True)
            results["corpus"] = run_corpus(seeds, runs / "corpus", args.corpus_root,
                                           rejudge=args.rejudge)
        if "maps" not in skip:
            print(f"{n_maps} random maps:", flush=True)
            results["maps"] = run_maps(n_maps, args.map_seed, args.base_root)
        if "step" not in skip:
            results["step"] = step_cost(args.base_root, 1 if args.quick else 3)
        if "paper" not in skip:
            results["paper"] = paper_scenarios(runs / "paper")
    load_after = os.getloadavg()
    rows = goal_rows(results)
    print(f"\nltl_maps_bench ({'quick' if args.quick else 'full'}; load average "
          f"{load_before[0]:.2f} before, {load_after[0]:.2f} after; "
          f"{time.perf_counter() - w0:.0f} s wall, {time.process_time() - c0:.0f} s CPU here)")
    print(f"{'goal':62s} {'measured':36s} {'target':26s} verdict")
    for goal, measured, target, ok in rows:
        verdict = "-" if ok is None else ("met" if ok else "NOT MET")
        print(f"{goal:62s} {measured:36s} {target:26s} {verdict}")
    payload = {"benchmark": "ltl_maps", "quick": args.quick, "seeds": seeds, "maps": n_maps,
               "machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                           "platform": platform.platform()},
               "load_average_before": list(load_before), "load_average_after": list(load_after),
               "results": results,
               "goals": [{"goal": g, "measured": m, "target": t, "met": ok}
                         for g, m, t, ok in rows]}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(payload, indent=2, default=str) + "\n")
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
