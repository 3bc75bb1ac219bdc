"""Goals of the paper's Scenarios 1–3: scenario × seed × mode × coupling-awareness.

    .venv/bin/python bench/scenario_bench.py [--quick] [--seeds 1 2 3 4 5]
        [--modes lockstep realtime] [--coupling on off] [--scenarios 1 2 3 recovery]
        [--keep DIR] [--rebuild DIR...] [--out FILE.json]

Every run is a real fleet (``tlfleet.coordinator.run.run_fleet``: router, sim and one process per
robot, as ``tlfleet run``); its report (``tlfleet.coordinator.report.run_report.build_report``)
gives the robustness of each STL sub-task from the trajectory, the verdicts and held fractions
(``tlfleet.coordinator.report.task_verdicts``), the LTL visits, contacts and stationary episodes.
The goals checked per run:

* S1: every sub-task ≥ its paper bound and within 0.05 of the best achievable of
  ``scenarios.md``; 0 contacts. Beside the goals of φ′3, φ′4, φ′5, their joint optimum
  (``tlfleet.coordinator.report.joint_optimum``, docs/coupling.md §3): ρ′4 + (ρ′3 + ρ′5)/2 ≤ −0.9
  from the scenario's geometry, each task's bound given the other two's ρ of the run, the distance
  to it, and φ′4's bound given robots 3 and 5's recorded trajectories (min over [5, 30] of
  1 − ‖z3 − z5‖/2), which tells how far the least-violating solution is from what was possible.
  The three goals (best − 0.05) leave zero slack on that plane;
* S2: ρ(φ3), ρ(φ4) ≥ −0.2; both LTL tasks accepting with every region visited ≥ 2 times;
  0 contacts; no robot stationary > 5 s while its task wants it to move;
* S3: every formation task ρ ≥ −0.1 and its predicate held ≥ 90 % of [10, 100]; the five
  regions visited; 0 contacts;
* recovery (``bench/recovery_case.toml``, coupling-aware limits off in the file; here ``--coupling
  on``/``off`` switches ``[stl] recovery`` instead, off being the paper's Algorithm 2 as a
  contrast): after a forced slowdown (the escort cannot keep up; repairs lower r̄ below 0) the
  leader stops, and the escort's ρ^ψ, recomputed from the trajectory, is ≥ 0 again within 10 s; 0
  contacts.

Each run directory gets ``bench_run.json`` (case, seed, mode, coupling, clean, wall time, load
average at its end); ``--keep DIR`` keeps them, ``--rebuild DIR`` recomputes the rows from kept
directories without running anything.

``--coupling off`` runs the scenario with ``[navigation] coupling_aware = false`` (the paper's
reactive leaders). Lockstep is deterministic and independent of the machine's load; realtime
depends on it (a shared 2-core machine: use it sparingly). CPU time of the children is not
measured here (``bench/runtime_bench.py`` does): the figures are outcomes, not speeds. Prints a
table and writes JSON to ``bench/results/scenario_bench.json`` (or ``--out``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from tlfleet.agent.scenario.loader import load_scenario  # noqa: E402
from tlfleet.agent.stl.monitor import read_trajectory_csv  # noqa: E402
from tlfleet.agent.stl.parser import robot_subtasks  # noqa: E402
from tlfleet.agent.stl.robustness import participants, psi_array  # noqa: E402
from tlfleet.coordinator.live.supervisor import SupervisorConfig  # noqa: E402
from tlfleet.coordinator.record.rundir import json_ready  # noqa: E402
from tlfleet.coordinator.record.typed_json import to_json  # noqa: E402
from tlfleet.coordinator.report.joint_optimum import find_pinches  # noqa: E402
from tlfleet.coordinator.report.run_report import build_report  # noqa: E402
from tlfleet.coordinator.run import RunConfig, run_fleet  # noqa: E402

CASES = {"1": ROOT / "scenarios" / "scenario1.toml", "2": ROOT / "scenarios" / "scenario2.toml",
         "3": ROOT / "scenarios" / "scenario3.toml",
         "recovery": ROOT / "bench" / "recovery_case.toml"}
S2_BOUND = -0.2
S3_BOUND = -0.1
S3_HELD = 0.9
S1_GAP = 0.05
RECOVERY_WITHIN = 10.0  # [s] ρ^ψ ≥ 0 again this soon after the leader stops
LEADER_STOPPED = 0.005  # [m/s] the leader counts as stopped below this speed


def scenario_file(case: str, coupling: bool, tmp: Path) -> Path:
    source = CASES[case]
    if case == "recovery":  # coupling_aware = false in the file; ``coupling`` switches recovery
        if coupling:
            return source
        path = tmp / "recovery_case_off.toml"
        path.write_text(source.read_text() + "\n[stl]\nrecovery = false\n")
        return path
    if coupling:
        return source
    path = tmp / f"scenario{case}_reactive.toml"
    path.write_text(source.read_text() + "\n[navigation]\ncoupling_aware = false\n")
    return path


def goals(number: int | str, data: dict) -> dict:
    """{goal name: bool} and the figures behind them, from a report's data."""
    subtasks = [(rid, s) for rid, e in data["stl"].items() for s in e["subtasks"]]
    verdicts = {(rid, row["label"]): row for rid, rows in data["verdicts"]["subtasks"].items()
                for row in rows}
    contacts = data["contacts"]["robot_robot"] + data["contacts"]["robot_wall"]
    stationary = data["verdicts"]["stationary"]
    out: dict = {"contacts": contacts, "stationary": len(stationary)}
    rho = {s["label"]: s["robustness"] for _rid, s in subtasks}
    out["rho"] = rho
    ok = {"no contact": contacts == 0}
    if number == 1:
        for _rid, s in subtasks:
            p = s["paper"]
            if p is None or s["robustness"] is None:
                ok[f"{s['label']} bound"] = False
                continue
            ok[f"{s['label']} ≥ paper"] = bool(p["met"])
            if p["best"] is not None:
                ok[f"{s['label']} within {S1_GAP} of best"] = s["robustness"] >= p["best"] - S1_GAP
    if number == 2:
        for _rid, s in subtasks:
            ok[f"{s['label']} ≥ {S2_BOUND}"] = (s["robustness"] is not None
                                                and s["robustness"] >= S2_BOUND)
        for rid, e in data["ltl"].items():
            visits = [v["trajectory"] if v["trajectory"] is not None else v["agent"]
                      for v in e["visits"].values()]
            ok[f"r{rid} accepting, visits ≥ 2"] = bool(e["accepting"]["met"]) and min(visits) >= 2
        ok["no deadlock"] = not stationary
    if number == 3:
        held = {}
        for rid, s in subtasks:
            row = verdicts[(rid, s["label"])]
            held[s["label"]] = row["held"]
            ok[f"{s['label']} ≥ {S3_BOUND}"] = (s["robustness"] is not None
                                                and s["robustness"] >= S3_BOUND)
            ok[f"{s['label']} held ≥ 90 %"] = row["held"] is not None and row["held"] >= S3_HELD
        out["held"] = held
        for rid, e in data["ltl"].items():
            visits = [v["trajectory"] if v["trajectory"] is not None else v["agent"]
                      for v in e["visits"].values()]
            ok[f"r{rid} five regions"] = len(visits) == 5 and min(visits) >= 1
    out["goals"] = ok
    out["met"] = all(ok.values())
    out["recoveries"] = sum(data["verdicts"]["recoveries"].values())
    return out


def one_run(case: str, seed: int, mode: str, coupling: bool, tmp: Path) -> dict:
    path = scenario_file(case, coupling, tmp)
    number = int(case) if case.isdigit() else case
    out = tmp / f"s{case}-seed{seed}-{mode}-{'on' if coupling else 'off'}"
    t0 = time.perf_counter()
    result = run_fleet(RunConfig(path, mode=mode, out=out, seed=seed, figures=False, rrd=False,
                                 supervisor=SupervisorConfig(ready_timeout=90.0,
                                                             wall_timeout=900.0)))
    wall = time.perf_counter() - t0
    meta = {"scenario": number, "seed": seed, "mode": mode,
            "coupling": coupling if number != "recovery" else False,
            "recovery_mechanism": coupling if number == "recovery" else True,
            "clean": result.clean, "wall_s": wall, "load_avg": list(os.getloadavg())}
    (out / "bench_run.json").write_text(json.dumps(meta, indent=2) + "\n")
    return evaluate(out, meta)


def evaluate(out: Path, meta: dict) -> dict:
    """The row of one run directory: its bench metadata and the goals from its report."""
    number = meta["scenario"]
    data = json_ready(to_json(build_report(out)))  # report.json's data
    row = {**meta, **goals(number, data)}
    scenario = load_scenario(out / "scenario.toml")
    traj = read_trajectory_csv(out / "trajectory.csv")
    row["joint"] = joint_rows(scenario, data, traj)
    if number == "recovery":
        row["recovery_goal"] = recovery_goal(scenario, data, traj)
        row["goals"][f"ρ ≥ 0 within {RECOVERY_WITHIN:g} s of the stop"] = \
            row["recovery_goal"]["met"]
        row["met"] = all(row["goals"].values())
    return row


def recovery_goal(scenario, data: dict, traj) -> dict:
    """The recovery case's goal (bench/recovery_case.toml): the escort's ρ^ψ, recomputed from the
    trajectory, is ≥ 0 again within RECOVERY_WITHIN of the leader's stop (its last sample faster
    than LEADER_STOPPED), after a slowdown that really lowered r (least r in force < 0)."""
    (escort,) = [r for r in scenario.robots if r.is_stl]
    (phi,) = robot_subtasks(escort)
    (leader,) = [j for j in participants(phi.body) if scenario.robot(j).is_ltl]
    xy = traj.states[leader][:, :2]
    speed = np.hypot(*np.diff(xy, axis=0).T) / np.diff(traj.t)
    moving = np.flatnonzero(speed > LEADER_STOPPED)
    t_stop = float(traj.t[moving[-1] + 1]) if moving.size else float(traj.t[0])
    rho = psi_array(phi.body, {j: traj.states[j] for j in participants(phi.body)})
    (sub,) = data["stl"][str(escort.id)]["subtasks"]
    after = traj.t >= t_stop
    back = traj.t[after & (rho >= 0.0)]
    t_back = float(back[0]) if back.size else None
    slowed = bool(sub["r_bar"] is not None and sub["r_bar"] < 0.0 and rho[~after].min() < 0.0)
    return {"t_stop": t_stop, "t_back": t_back, "rho_at_stop": float(rho[after][0]),
            "r_bar": sub["r_bar"], "r_final": sub["r_final"], "slowed": slowed,
            "delay": None if t_back is None else t_back - t_stop,
            "rho_min_after_back": None if t_back is None else float(rho[traj.t >= t_back].min()),
            "met": slowed and t_back is not None and t_back - t_stop <= RECOVERY_WITHIN}


def joint_rows(scenario, data: dict, traj) -> list[dict]:
    """Per pinch of the scenario (``tlfleet.coordinator.report.joint_optimum``; Scenario 1's φ′3,
    φ′4, φ′5), each task's ρ, its goal (best of scenarios.md − S1_GAP), and its jointly achievable
    bound given the other two tasks' ρ of this run (for the leader also given robots j and k's
    trajectories)."""
    entry = {int(rid): {s["index"]: s for s in e["subtasks"]} for rid, e in data["stl"].items()}
    out = []
    for pinch in find_pinches(scenario):
        lead = entry[pinch.leader][pinch.leader_index]
        rj, rk = (entry[r.robot][r.index] for r in pinch.regions)
        rho = [lead["robustness"], rj["robustness"], rk["robustness"]]
        if any(v is None or not np.isfinite(v) for v in rho):
            continue
        bounds = [pinch.leader_bound(rho[1], rho[2]), pinch.region_bound(0, rho[0], rho[2]),
                  pinch.region_bound(1, rho[0], rho[1])]
        tasks = []
        for k, (sub, bound) in enumerate(zip((lead, rj, rk), bounds, strict=True)):
            best = sub["paper"]["best"] if sub["paper"] else None
            others = [x["label"] for i, x in enumerate((lead, rj, rk)) if i != k]
            tasks.append({"label": sub["label"], "rho": rho[k], "best": best,
                          "goal": None if best is None else best - S1_GAP,
                          "joint_bound": bound, "given": others, "to_joint": rho[k] - bound})
        goal = [t["goal"] for t in tasks]
        tasks[0]["trajectory_bound"] = pinch.trajectory_bound(traj)
        tasks[0]["to_trajectory_bound"] = rho[0] - tasks[0]["trajectory_bound"]
        out.append({"plane": pinch.plane, "tasks": tasks,
                    "robots": [pinch.leader, *(r.robot for r in pinch.regions)],
                    "goal_slack": (None if None in goal else
                                   round(pinch.plane - goal[0] - (goal[1] + goal[2]) / 2, 12))})
    return out


def render_joint(joint: list[dict]) -> list[str]:
    """The joint-optimum table of one run (``joint_rows``)."""
    lines = []
    for p in joint:
        lead, rj, rk = (t["label"] for t in p["tasks"])
        _, zj, zk = p["robots"]
        slack = "–" if p["goal_slack"] is None else f"{p['goal_slack'] + 0.0:+.3f}"
        lines.append(f"      joint optimum: ρ({lead}) + (ρ({rj}) + ρ({rk}))/2 ≤ {p['plane']:+.3f}; "
                     f"slack of the three goals {slack}")
        lines.append(f"      {'task':<6}{'ρ':>8}{'goal':>8}  {'met':<4}{'joint bound':>12}"
                     f"  {'given':<11}{'ρ − bound':>10}")
        for t in p["tasks"]:
            goal = "–" if t["goal"] is None else f"{t['goal']:+.3f}"
            met = "–" if t["goal"] is None else ("yes" if t["rho"] >= t["goal"] else "NO")
            extra = ""
            if "trajectory_bound" in t:
                extra = (f"; given z{zj}, z{zk}: {t['trajectory_bound']:+.3f} "
                         f"(ρ − it {t['to_trajectory_bound']:+.3f})")
            lines.append(f"      {t['label']:<6}{t['rho']:>+8.3f}{goal:>8}  {met:<4}"
                         f"{t['joint_bound']:>+12.3f}  {', '.join(t['given']):<11}"
                         f"{t['to_joint']:>+10.3f}{extra}")
    return lines


def _switch(row: dict) -> str:
    """The column 'coupl': coupling-aware limits, or for the recovery case recovery itself."""
    if row["scenario"] == "recovery":
        return "rec " + ("on" if row.get("recovery_mechanism", True) else "off")
    return "on" if row["coupling"] else "off"


def render(rows: list[dict]) -> str:
    lines = [f"{'scen':<5}{'seed':>5} {'mode':<9}{'coupl':<8}{'met':<5} figures"]
    for r in rows:
        rho = ", ".join(f"{k} {v:+.3f}" for k, v in r["rho"].items() if isinstance(v, float))
        held = (", held " + ", ".join(f"{k} {100 * v:.0f}%" for k, v in r["held"].items()
                                      if v is not None)) if r.get("held") else ""
        if r.get("recovery_goal"):
            g = r["recovery_goal"]
            back = "never" if g["t_back"] is None else f"{g['t_back']:.2f} s (+{g['delay']:.2f} s)"
            rho += (f"; leader stopped {g['t_stop']:.2f} s (ρ^ψ {g['rho_at_stop']:+.3f}, r̄ "
                    f"{g['r_bar']:+.3f}), ρ^ψ ≥ 0 at {back}")
            if g["rho_min_after_back"] is not None:
                rho += f", min after {g['rho_min_after_back']:+.3f}"
        failed = [k for k, v in r["goals"].items() if not v]
        name = f"S{r['scenario']}" if isinstance(r["scenario"], int) else "rec"  # "on": recovery
        lines.append(f"{name:<5}{r['seed']:>5} {r['mode']:<9}"
                     f"{_switch(r):<8}{'yes' if r['met'] else 'NO':<5}"
                     f"{rho}{held}; contacts {r['contacts']}, stationary {r['stationary']}, "
                     f"recoveries {r['recoveries']}"
                     + (f"; failed: {', '.join(failed)}" if failed else ""))
        lines.extend(render_joint(r.get("joint", [])))
    return "\n".join(lines)


def render_goals(rows: list[dict]) -> str:
    """Per case × mode × switch: each goal met in how many runs, and the range of each figure."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        name = f"S{r['scenario']}" if isinstance(r["scenario"], int) else "recovery"
        groups.setdefault((name, r["mode"], _switch(r)), []).append(r)
    lines = ["goals (met in k of n runs; figures: min … max over the runs; load: 1-min load "
             "average at the runs' ends)"]
    for (name, mode, switch), runs in groups.items():
        seeds = ",".join(str(r["seed"]) for r in runs)
        loads = [r["load_avg"][0] for r in runs if r.get("load_avg")]
        load = f", load {min(loads):.1f}–{max(loads):.1f}" if loads else ""
        lines.append(f"  {name} {mode} {switch} (seeds {seeds}{load}):")
        for goal in runs[0]["goals"]:
            met = sum(bool(r["goals"].get(goal)) for r in runs)
            lines.append(f"    {'ok ' if met == len(runs) else 'NOT'} {goal}: {met}/{len(runs)}")
        for label in runs[0]["rho"]:
            values = [r["rho"][label] for r in runs if isinstance(r["rho"].get(label), float)]
            if values:
                lines.append(f"        ρ {label} {min(values):+.3f} … {max(values):+.3f}")
        for label in (runs[0].get("held") or {}):
            values = [r["held"][label] for r in runs if r["held"].get(label) is not None]
            if values:
                lines.append(f"        held {label} {100 * min(values):.0f} … "
                             f"{100 * max(values):.0f} %")
        delays = [r["recovery_goal"]["delay"] for r in runs
                  if r.get("recovery_goal") and r["recovery_goal"]["delay"] is not None]
        if delays:
            lines.append(f"        ρ^ψ ≥ 0 after the stop: {min(delays):.2f} … {max(delays):.2f} s")
        for k, label in enumerate(t["label"] for t in (runs[0].get("joint") or [{}])[0].get(
                "tasks", [])):
            gaps = [r["joint"][0]["tasks"][k]["to_joint"] for r in runs if r.get("joint")]
            lines.append(f"        {label} − its joint bound {min(gaps):+.3f} … {max(gaps):+.3f}")
            if k == 0:
                gaps = [r["joint"][0]["tasks"][0]["to_trajectory_bound"] for r in runs
                        if r.get("joint")]
                lines.append(f"        {label} − its bound given the recorded trajectories "
                             f"{min(gaps):+.3f} … {max(gaps):+.3f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="seed 1, lockstep, coupling on")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--modes", nargs="+", default=["lockstep"],
                        choices=["lockstep", "realtime"])
    parser.add_argument("--coupling", nargs="+", default=["on", "off"], choices=["on", "off"])
    parser.add_argument("--scenarios", nargs="+", default=list(CASES), choices=list(CASES),
                        help="the paper's scenarios 1–3 and the recovery case")
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "results"
                        / "scenario_bench.json")
    parser.add_argument("--keep", type=Path, default=None,
                        help="keep the run directories under this folder (default: a temporary "
                             "one, removed at the end)")
    parser.add_argument("--rebuild", type=Path, nargs="+", default=None,
                        help="run nothing: rebuild the rows from run directories kept with "
                             "--keep (each has its bench_run.json)")
    args = parser.parse_args(argv)
    if args.quick:
        args.seeds, args.modes, args.coupling = [1], ["lockstep"], ["on"]
    rows = []
    if args.rebuild is not None:
        runs = sorted(m.parent for d in args.rebuild for m in d.glob("*/bench_run.json"))
        if not runs:
            parser.error(f"no run directory with bench_run.json under {args.rebuild}")
        rows = [evaluate(d, json.loads((d / "bench_run.json").read_text())) for d in runs]
        rows.sort(key=lambda r: (str(r["scenario"]), not r["coupling"],
                                 not r.get("recovery_mechanism", True), r["mode"], r["seed"]))
    else:
        with tempfile.TemporaryDirectory(prefix="scenario_bench_") as tmp:
            keep = args.keep if args.keep is not None else Path(tmp)
            keep.mkdir(parents=True, exist_ok=True)
            for case in args.scenarios:
                # the recovery case keeps coupling-aware limits off; its "off" is recovery off
                for coupling in args.coupling:
                    for mode in args.modes:
                        for seed in args.seeds:
                            row = one_run(case, seed, mode, coupling == "on", keep)
                            rows.append(row)
                            print(render([row]).splitlines()[1], flush=True)
    print()
    print(render(rows))
    print()
    print(render_goals(rows))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"machine": platform.platform(), "rows": rows}, indent=2,
                                   ensure_ascii=False) + "\n")
    print(f"\nJSON: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
