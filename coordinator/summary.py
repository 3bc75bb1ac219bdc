"""The plain-text run summary: a pure function of a run directory's files (architecture.md §6).

:func:`summarise_run` reads ``scenario.toml``, ``trajectory.csv``, ``status.csv``,
``events.jsonl`` and ``run.json`` (all optional but the scenario) once (:func:`read_run_files`,
shared with ``coordinator.report``) and returns ``(text, data)`` (:func:`summarise`):

* per STL robot and sub-task, the **standard** robustness (min/max semantics, stl-funnel.md §3)
  recomputed offline from the trajectory with ``agent.stl.monitor``, the last r̄ reported for the
  sub-task, and the repair counts per stage (from the last status and from ``repair`` events);
* per LTL robot, visits per region (reported by the agent, and recounted from the trajectory as
  entries into the region disc), GF rounds, and whether every region of its plan was visited;
* contacts (robot–robot, robot–wall) from ``contact`` events, and the closest approach of two
  robots in the trajectory (centre distance minus both radii) [m];
* deadline statistics: ``deadline_miss``, ``watchdog_stop``, ``stale_mocap`` and
  ``malformed_message`` events (``data.count``, when present, is the running total of that
  source on ``data.key``: the last one counts), plus the malformed payloads the coordinator
  itself received; the simulator's ``sim_stats`` event (control deadlines due/missed, frame →
  command latency percentiles [ms]);
* process deaths (``process_died`` events).
"""

from __future__ import annotations

import csv
import json
import logging
import math
import re
from collections import Counter, defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agent.errors import TlfleetError
from agent.scenario import Scenario, load_scenario
from agent.stl.monitor import Trajectory, evaluate_trajectory, read_trajectory_csv

logger = logging.getLogger(__name__)

REGION_HYSTERESIS = 0.05  # [m] a robot must leave a region by this much before re-entering counts


def read_events(path: Path) -> list[dict[str, Any]]:
    """The events of ``events.jsonl``; a torn last line (crash) is skipped."""
    return read_events_checked(path)[0]


def read_events_checked(path: Path) -> tuple[list[dict[str, Any]], list[int]]:
    """The events of ``events.jsonl`` and the 1-based numbers of the lines skipped (not JSON, e.g.
    a line torn by a crash, or not an object)."""
    events: list[dict[str, Any]] = []
    skipped: list[int] = []
    if not path.exists():
        return events, skipped
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            logger.warning("%s:%d: not JSON, skipped", path, number)
            skipped.append(number)
            continue
        if isinstance(record, dict):
            record.setdefault("data", {})
            events.append(record)
        else:
            skipped.append(number)
    return events, skipped


def read_statuses(path: Path) -> list[dict[str, str]]:
    if not path.exists():
        return []
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def region_entries(xy: np.ndarray, center: tuple[float, float], radius: float,
                   hysteresis: float = REGION_HYSTERESIS) -> int:
    """Entries of the points ``xy`` (N, 2) [m] into the disc (center, radius); starting inside
    counts as one; a re-entry counts only after leaving the disc by ``hysteresis``."""
    return len(region_entry_indices(xy, center, radius, hysteresis))


def region_entry_indices(xy: np.ndarray, center: tuple[float, float], radius: float,
                         hysteresis: float = REGION_HYSTERESIS) -> list[int]:
    """Sample indices of the entries counted by :func:`region_entries` (0 if starting inside)."""
    if len(xy) == 0:
        return []
    d = np.hypot(xy[:, 0] - center[0], xy[:, 1] - center[1])
    entries: list[int] = []
    inside = False
    for k, value in enumerate(d):
        if not inside and value <= radius:
            entries.append(k)
            inside = True
        elif inside and value > radius + hysteresis:
            inside = False
    return entries


def closest_approach(traj: Trajectory, radii: dict[int, float]) -> dict[str, Any] | None:
    """Min over samples and pairs of ‖p_i − p_j‖ − r_i − r_j [m], with the pair and time."""
    ids = [r for r in traj.robot_ids if r in radii]
    best: dict[str, Any] | None = None
    for k, i in enumerate(ids):
        for j in ids[k + 1:]:
            gap = (np.hypot(*(traj.states[i][:, :2] - traj.states[j][:, :2]).T)
                   - radii[i] - radii[j])
            n = int(np.argmin(gap))
            if best is None or gap[n] < best["gap"]:
                best = {"pair": [i, j], "gap": float(gap[n]), "t": float(traj.t[n])}
    return best


def _float(text: str | None) -> float:
    try:
        return float(text) if text not in (None, "") else math.nan
    except ValueError:
        return math.nan


def _int(text: str | None, default: Any) -> Any:
    value = _float(text)
    return int(value) if math.isfinite(value) else default


def _json_cell(text: str | None, default: Any) -> Any:
    try:
        return json.loads(text) if text else default
    except json.JSONDecodeError:
        return default


def _count(event: dict[str, Any]) -> int:
    count = event.get("data", {}).get("count", 1)
    return int(count) if isinstance(count, (int, float)) and count >= 0 else 1


def _number(value: float) -> float | str | None:
    """JSON-ready: ±inf (empty window) as "inf"/"-inf"; NaN (not evaluated) as None."""
    if math.isnan(value):
        return None
    return value if math.isfinite(value) else ("inf" if value > 0 else "-inf")


def _ltl_regions(scenario: Scenario, formula: str) -> list[str]:
    names = {r.name for r in scenario.regions}
    return sorted({tok for tok in re.findall(r"[A-Za-z_][A-Za-z0-9_]*", formula) if tok in names})


@dataclass(frozen=True)
class RunFiles:
    """The files of a run directory, each read once (the summary and the report share them)."""

    run_dir: Path
    scenario: Scenario
    info: dict[str, Any]  # run.json ({} when missing)
    events: list[dict[str, Any]]  # events.jsonl, lines that are not JSON objects skipped
    skipped_event_lines: list[int]  # their 1-based numbers
    statuses: list[dict[str, str]]  # status.csv rows
    traj: Trajectory | None  # trajectory.csv, None when it cannot be read
    traj_error: str  # why not ("" when read)


def read_run_files(run_dir: str | Path) -> RunFiles:
    """Read ``run_dir``'s scenario (required), run.json, events, statuses and trajectory."""
    run_dir = Path(run_dir)
    scenario = load_scenario(run_dir / "scenario.toml")
    info = _json_cell((run_dir / "run.json").read_text(encoding="utf-8")
                      if (run_dir / "run.json").exists() else "", {})
    events, skipped = read_events_checked(run_dir / "events.jsonl")
    traj: Trajectory | None = None
    traj_error = ""
    try:
        traj = read_trajectory_csv(run_dir / "trajectory.csv")
    except TlfleetError as exc:
        traj_error = str(exc)
    return RunFiles(run_dir, scenario, info, events, skipped,
                    read_statuses(run_dir / "status.csv"), traj, traj_error)


def summarise_run(run_dir: str | Path) -> tuple[str, dict[str, Any]]:
    """(text, data) summary of the run in ``run_dir``; see the module docstring."""
    return summarise(read_run_files(run_dir))


def summarise(files: RunFiles) -> tuple[str, dict[str, Any]]:
    """(text, data) summary of a run directory's files (read by :func:`read_run_files`)."""
    run_dir, scenario, info = files.run_dir, files.scenario, files.info
    events, statuses, traj, traj_error = files.events, files.statuses, files.traj, files.traj_error
    data: dict[str, Any] = {
        "scenario": scenario.name, "run_dir": str(run_dir), "run": info,
        "frames": 0 if traj is None else len(traj.t),
        "t_end": 0.0 if traj is None else float(traj.t[-1]),
        "trajectory_error": traj_error,
    }
    data["stl"] = _stl_section(scenario, run_dir, traj, statuses, events)
    data["ltl"] = _ltl_section(scenario, traj, statuses)
    data["contacts"] = _contacts(events)
    radii = {r.id: r.radius for r in scenario.robots}
    data["closest_approach"] = None if traj is None else closest_approach(traj, radii)
    data["deadlines"] = _deadlines(events, info)
    data["process_deaths"] = [
        {"t": e.get("t"), **{k: v for k, v in e["data"].items()}}
        for e in events if e.get("kind") == "process_died"]
    return format_summary(data), data


def _stl_section(scenario: Scenario, run_dir: Path, traj: Trajectory | None,
                 statuses: list[dict[str, str]], events: list[dict[str, Any]]) -> dict:
    last: dict[tuple[int, int], dict[str, str]] = {}
    for row in statuses:
        if row.get("kind") == "stl":
            last[(int(row["robot"]), _int(row.get("subtask"), 0))] = row
    repairs: dict[int, Counter[int]] = defaultdict(Counter)
    for e in events:
        if e.get("kind") == "repair" and str(e.get("source", "")).startswith("agent/"):
            robot = int(str(e["source"]).split("/", 1)[1])
            stage = e["data"].get("stage")
            if isinstance(stage, int):
                repairs[robot][stage] += 1
    robust: dict[int, Any] = {}
    error = ""
    if traj is not None:
        try:
            robust = evaluate_trajectory(scenario, traj, run_dir / "trajectory.csv")
        except (TlfleetError, KeyError) as exc:
            error = str(exc)
    out: dict[int, Any] = {}
    for robot in sorted(scenario.robots, key=lambda r: r.id):
        if not robot.is_stl:
            continue
        entry = robust.get(robot.id)
        subtasks = []
        texts = entry["subtasks"] if entry else [{"task": t, "window": None,
                                                  "robustness": math.nan} for t in robot.stl]
        for index, sub in enumerate(texts):
            status = last.get((robot.id, index))
            stages = _json_cell(status.get("events") if status else "", [0, 0, 0])
            subtasks.append({
                "task": sub["task"], "window": sub["window"],
                "robustness": _number(sub["robustness"]),
                "r_last": _number(_float(status.get("r"))) if status else None,
                "repairs_status": stages,
            })
        out[robot.id] = {
            "robustness": _number(entry["robustness"]) if entry else None,
            "subtasks": subtasks,
            "repair_events": {str(s): n for s, n in sorted(repairs[robot.id].items())},
            "error": error,
        }
    return out


def _ltl_section(scenario: Scenario, traj: Trajectory | None,
                 statuses: list[dict[str, str]]) -> dict:
    last: dict[int, dict[str, str]] = {}
    for row in statuses:
        if row.get("kind") == "ltl":
            last[int(row["robot"])] = row
    regions = {r.name: r for r in scenario.regions}
    out: dict[int, Any] = {}
    for robot in sorted(scenario.robots, key=lambda r: r.id):
        if robot.ltl is None:
            continue
        status = last.get(robot.id)
        reported = {}
        plan: list[str] = []
        rounds = None
        if status:
            reported = {str(k): int(v) for k, v in _json_cell(status.get("visits"), [])}
            plan = [name for name in _json_cell(status.get("prefix"), [])
                    + _json_cell(status.get("suffix"), []) if name in regions]
            rounds = _int(status.get("rounds"), None)
        names = sorted(set(plan) | set(_ltl_regions(scenario, robot.ltl)))
        recount = {}
        if traj is not None and robot.id in traj.states:
            xy = traj.states[robot.id][:, :2]
            recount = {n: region_entries(xy, regions[n].center, regions[n].radius)
                       for n in names}
        plan_regions = sorted(set(plan)) or names
        out[robot.id] = {
            "task": robot.ltl, "plan_regions": plan_regions, "visits_reported": reported,
            "visits_trajectory": recount, "rounds": rounds,
            "all_plan_regions_visited": bool(plan_regions) and all(
                max(reported.get(n, 0), recount.get(n, 0)) > 0 for n in plan_regions),
        }
    return out


def _contacts(events: list[dict[str, Any]]) -> dict[str, Any]:
    pairs: Counter[str] = Counter()
    robot_robot = robot_wall = 0
    for e in events:
        if e.get("kind") != "contact":
            continue
        a, b = e["data"].get("a"), e["data"].get("b")
        if "wall" in (a, b):
            robot_wall += 1
            pairs[f"{a if b == 'wall' else b}-wall"] += 1
        else:
            robot_robot += 1
            pairs["-".join(str(x) for x in sorted((a, b), key=str))] += 1
    return {"robot_robot": robot_robot, "robot_wall": robot_wall, "pairs": dict(pairs)}


def _deadlines(events: list[dict[str, Any]], info: dict[str, Any]) -> dict[str, Any]:
    misses: Counter[str] = Counter()
    malformed: Counter[str] = Counter()
    counts: Counter[str] = Counter()
    running: dict[tuple[str, str], int] = {}
    for e in events:
        kind = e.get("kind")
        if kind == "deadline_miss":
            misses[str(e["data"].get("robot"))] += _count(e)
        elif kind == "malformed_message":
            source, data = str(e.get("source")), e.get("data", {})
            count = data.get("count")
            if isinstance(count, int) and count >= 0:  # a running total per (source, key)
                key = (source, str(data.get("key")))
                running[key] = max(running.get(key, 0), count)
            else:
                malformed[source] += 1
        elif kind in ("watchdog_stop", "stale_mocap"):
            counts[kind] += 1
    for (source, _key), n in running.items():
        malformed[source] += n
    for what, n in (info.get("malformed_received") or {}).items():
        malformed[f"coordinator ({what})"] += int(n)
    stats = next((e["data"] for e in reversed(events) if e.get("kind") == "sim_stats"), None)
    return {"deadline_miss": sum(misses.values()), "deadline_miss_by_robot": dict(misses),
            "sim_stats": stats,
            "watchdog_stop": counts["watchdog_stop"], "stale_mocap": counts["stale_mocap"],
            "malformed": sum(malformed.values()), "malformed_by_source": dict(malformed)}


def _fmt(value: Any, spec: str = "+.4f") -> str:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return format(value, spec) if math.isfinite(value) else str(value)
    return str(value)


def format_summary(data: dict[str, Any]) -> str:
    """The text of ``summary.txt`` from the dict of :func:`summarise_run`."""
    run = data.get("run") or {}
    lines = [f"run {data['scenario']}  ({data['run_dir']})"]
    head = f"  {data['frames']} frames, t_end = {data['t_end']:.2f} s"
    if run.get("mode"):
        head += f", {run['mode']}"
    if run.get("wall_time") is not None:
        head += f", wall {run['wall_time']:.1f} s"
    lines.append(head)
    if data["trajectory_error"]:
        lines.append(f"  trajectory: {data['trajectory_error']}")
    if data["stl"]:
        lines.append("STL robots (standard robustness from trajectory.csv):")
    for rid, entry in data["stl"].items():
        stages = ", ".join(f"stage {s}: {n}" for s, n in entry["repair_events"].items())
        lines.append(f"  robot {rid}: rho = {_fmt(entry['robustness'])}"
                     + (f"   repair events {stages}" if stages else ""))
        for sub in entry["subtasks"]:
            extra = ""
            if sub["r_last"] is not None:
                extra = (f"   r̄_last = {_fmt(sub['r_last'])}   repairs per stage "
                         f"{'/'.join(str(n) for n in sub['repairs_status'])}")
            lines.append(f"    {_fmt(sub['robustness'])}  {sub['task']}{extra}")
        if entry["error"]:
            lines.append(f"    ({entry['error']})")
    if data["ltl"]:
        lines.append("LTL robots (visits: reported by the agent / entries in the trajectory):")
    for rid, entry in data["ltl"].items():
        visits = ", ".join(f"{n} {entry['visits_reported'].get(n, 0)}/"
                           f"{entry['visits_trajectory'].get(n, '-')}"
                           for n in entry["plan_regions"])
        ok = "all plan regions visited" if entry["all_plan_regions_visited"] else \
            "NOT all plan regions visited"
        rounds = "" if entry["rounds"] is None else f", GF rounds {entry['rounds']}"
        lines.append(f"  robot {rid}: {entry['task']}: {visits}{rounds}; {ok}")
    c = data["contacts"]
    lines.append(f"contacts: robot-robot {c['robot_robot']}, robot-wall {c['robot_wall']}"
                 + (f" ({', '.join(f'{k}: {v}' for k, v in sorted(c['pairs'].items()))})"
                    if c["pairs"] else ""))
    if data["closest_approach"]:
        ca = data["closest_approach"]
        lines.append(f"closest approach: robots {ca['pair'][0]} and {ca['pair'][1]}, gap "
                     f"{ca['gap']:+.3f} m at t = {ca['t']:.2f} s")
    d = data["deadlines"]
    by_robot = ", ".join(f"{k}: {v}" for k, v in sorted(d["deadline_miss_by_robot"].items()))
    by_source = ", ".join(f"{k}: {v}" for k, v in sorted(d["malformed_by_source"].items()))
    lines.append(f"deadlines: {d['deadline_miss']} missed" + (f" ({by_robot})" if by_robot else "")
                 + f", watchdog stops {d['watchdog_stop']}, stale-mocap {d['stale_mocap']}")
    stats = d.get("sim_stats")
    if stats and stats.get("due"):
        timing = (f"control deadlines (sim): {stats.get('missed', 0)} of {stats['due']} missed "
                  f"({100.0 * stats.get('missed', 0) / stats['due']:.3f} %)")
        if "latency_p50_ms" in stats:
            timing += (f", frame→command latency p50 {stats['latency_p50_ms']:.2f} ms, "
                       f"p99 {stats['latency_p99_ms']:.2f} ms")
        lines.append(timing)
    lines.append(f"malformed messages: {d['malformed']}" + (f" ({by_source})" if by_source else ""))
    deaths = data["process_deaths"]
    lines.append(f"process deaths: {len(deaths)}" + "".join(
        f"\n  {x.get('process')} at t = {_fmt(x.get('t'), '.2f')} s ({x.get('how', '')})"
        for x in deaths))
    return "\n".join(lines)


def write_summary(run_dir: str | Path) -> tuple[str, dict[str, Any]]:
    """Compute the summary and write ``summary.txt`` and ``summary.json`` into ``run_dir``."""
    text, data = summarise_run(run_dir)
    run_dir = Path(run_dir)
    (run_dir / "summary.txt").write_text(text + "\n", encoding="utf-8")
    (run_dir / "summary.json").write_text(json.dumps(data, indent=2, default=str) + "\n",
                                          encoding="utf-8")
    return text, data
