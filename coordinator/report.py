"""The run report: ``report.md``, ``report.json`` and figures of a run (architecture.md §6).

:func:`build_report` reads a run directory (``scenario.toml`` required; ``trajectory.csv``,
``status.csv``, ``events.jsonl``, ``run.json`` optional) and returns a :class:`Report`;
:func:`write_report` also writes ``report.md``, ``report.json`` and the PNG figures
(``coordinator.figures``). The numbers the plain summary already computes come from
:func:`coordinator.summary.summarise` (on the files read once by
:func:`coordinator.summary.read_run_files`); this module adds:

**STL sub-tasks.** Beside the standard robustness ρ (min/max semantics, from the trajectory) and
the guaranteed bound r̄ the agent ended the sub-task with, the paper's reported lower bound and the
best achievable value (``coordinator.paper_values``, matched by scenario name *and* canonical
sub-task text) with ``met`` ⇔ ρ ≥ bound, and ``gap_to_best`` = ρ − best. Repairs per stage come
from the agent's counters (last status row of the sub-task) and from ``repair`` events
(``data.subtask``, ``data.stage``).

**LTL robots: the executed word and its accepting condition.** Definitions (ltl-planning.md §3,
the planner's transition system):

* *word*: the robot's region visits in time order. A visit is an entry into a region's disc with
  the hysteresis of :func:`coordinator.summary.region_entries` (re-entry counts only after leaving
  by ``REGION_HYSTERESIS``); consecutive visits of the same region collapse into one (a stutter).
  Each visit is the letter ``labels(region)``. Travel between regions is *not* a letter (the
  transition system jumps region to region); a robot that starts outside every region starts with
  the letter ∅ (the planner's ``start`` state). Collapsing stutters is exact for X-free formulas
  (stutter-invariant), the only ones the scenarios use.
* *plan cycle*: the suffix of the plan in the last LTL status row (``prefix``/``suffix``; the
  plan is recomputed with ``agent.ltl.planner.plan_robot`` only when there is no status row),
  collapsed cyclically: ``[a12, a11, a12]`` → ``c = (a12, a11)``.
* *completed cycle*: when ``|c| ≥ 2``, every index ``j`` of the word with
  ``word[j−|c| … j] = c₀ c₁ … c_{|c|−1} c₀``; its *cycle time* is the time between the entries at
  ``j − |c|`` and ``j`` [s] (for back-to-back cycles, the time between successive completions).
  A suffix of one region (a task that needs no cycle, e.g. ``F a & F b``) has no cycles.
* *lasso*: with at least one completed cycle, the last one ending at ``j`` closes the run:
  ``u = word[0 … j−|c|)`` and ``v = word[j−|c| … j)``; otherwise (no cycle needed, or none
  completed) ``u = word[0 … n−1)`` and ``v = word[n−1]``: the robot's final label repeated forever.
* *accepting condition met* ⇔ ``u·v^ω ⊨ φ`` by the exact lasso evaluator ``agent.ltl.lasso.holds``
  **and** the Büchi automaton ``agent.ltl.buchi.translate(φ)`` accepts ``u·v^ω``
  (:func:`agent.ltl.emptiness.accepts_lasso`); both are reported and must agree. A robot that
  never completes the cycle its task needs therefore does not meet it (its final label repeated
  does not satisfy ``G F a & G F b``).

Everything else (contacts, closest approach, deadline and latency statistics from ``sim_stats``,
process deaths) is the summary's.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agent.errors import TlfleetError, UnsatisfiableTask
from agent.ltl.buchi import translate
from agent.ltl.emptiness import accepts_lasso
from agent.ltl.lasso import holds
from agent.ltl.planner import plan_robot
from agent.scenario import Scenario
from agent.stl.monitor import Trajectory
from agent.stl.parser import parse_task
from coordinator import paper_values, verdicts
from coordinator.summary import REGION_HYSTERESIS, read_run_files, region_entry_indices, summarise

SCHEMA = 1
START = "start"  # the planner's name of the state outside every region (ltl-planning.md §3)


class RunDirectoryError(TlfleetError, ValueError):
    """A run directory that cannot be reported on: names the directory or file and why."""

    def __init__(self, path: Path, reason: str):
        self.path, self.reason = path, reason
        super().__init__(f"{path}: {reason}")


@dataclass
class Report:
    """A run's report: ``data`` is report.json, ``markdown`` report.md, ``table`` the console
    table, ``figures`` the PNG files (written, or already present for :func:`build_report`)."""

    run_dir: Path
    data: dict[str, Any]
    markdown: str
    table: str
    figures: list[Path] = field(default_factory=list)


# ----------------------------------------------------------------------------------------------
# LTL: executed word, cycles, lasso, acceptance


def region_word(t: np.ndarray, xy: np.ndarray, scenario: Scenario,
                hysteresis: float = REGION_HYSTERESIS) -> list[tuple[float, str]]:
    """The executed word as ``[(entry time [s], region name)]`` (see the module docstring):
    ``t`` (N,) [s], ``xy`` (N, 2) [m]; ``"start"`` at t[0] if no region holds the first sample."""
    if len(t) == 0:
        return []
    entries = sorted((k, region.name) for region in scenario.regions
                     for k in region_entry_indices(xy, region.center, region.radius, hysteresis))
    word: list[tuple[float, str]] = []
    if not entries or entries[0][0] != 0:
        word.append((float(t[0]), START))
    for k, name in entries:
        if not word or word[-1][1] != name:
            word.append((float(t[k]), name))
    return word


def plan_cycle(suffix: list[str]) -> list[str]:
    """The plan's suffix with consecutive repeats collapsed cyclically: [a, b, a] → [a, b]."""
    cycle: list[str] = []
    for name in suffix:
        if not cycle or cycle[-1] != name:
            cycle.append(name)
    while len(cycle) > 1 and cycle[-1] == cycle[0]:
        cycle.pop()
    return cycle


def completed_cycles(names: list[str], cycle: list[str]) -> list[int]:
    """Indices ``j`` of ``names`` closing the cycle: ``names[j−k … j] == cycle + [cycle[0]]``."""
    k = len(cycle)
    if k < 2:
        return []
    pattern = [*cycle, cycle[0]]
    return [j for j in range(k, len(names)) if names[j - k:j + 1] == pattern]


def _labels(scenario: Scenario, name: str) -> frozenset[str]:
    return frozenset() if name == START else scenario.region(name).labels


def _ltl_robot(scenario: Scenario, robot_id: int, traj: Trajectory | None,
               status: dict[str, str] | None, summary_entry: dict[str, Any]) -> dict[str, Any]:
    robot = scenario.robot(robot_id)
    formula = robot.ltl or ""
    plan: dict[str, Any]
    if status is not None:
        plan = {"prefix": _json_list(status.get("prefix")),
                "suffix": _json_list(status.get("suffix")),
                "source": "status.csv (last LTL status row)"}
    else:
        try:
            p = plan_robot(scenario, robot_id)
            plan = {"prefix": list(p.prefix), "suffix": list(p.suffix),
                    "source": "recomputed (no LTL status row)"}
        except UnsatisfiableTask as exc:
            plan = {"prefix": [], "suffix": [], "source": f"none ({exc})"}
    visits = {name: {"agent": summary_entry["visits_reported"].get(name, 0),
                     "trajectory": summary_entry["visits_trajectory"].get(name)}
              for name in summary_entry["plan_regions"]}
    entry: dict[str, Any] = {
        "task": formula, "plan": plan, "visits": visits, "rounds": summary_entry["rounds"],
        "word": [], "cycle": plan_cycle(plan["suffix"]), "cycles_completed": 0,
        "cycle_times": [], "cycle_time_mean": None, "lasso": None,
        "accepting": {"lasso": None, "buchi": None, "agree": None, "met": False},
        "note": "",
    }
    if traj is None or robot_id not in traj.states:
        entry["note"] = "no trajectory for this robot: accepting condition not evaluated"
        return entry
    word = region_word(traj.t, traj.states[robot_id][:, :2], scenario)
    names = [name for _t, name in word]
    times = [t for t, _name in word]
    cycle = entry["cycle"]
    ends = completed_cycles(names, cycle)
    cycle_times = [times[j] - times[j - len(cycle)] for j in ends]
    if ends:
        j = ends[-1]
        u, v = names[:j - len(cycle)], names[j - len(cycle):j]
        closed_by = f"last completed cycle (ends at t = {times[j]:.2f} s)"
    else:
        u, v = names[:-1], names[-1:]
        closed_by = ("final label repeated (the plan needs no cycle)" if len(cycle) < 2
                     else "final label repeated (no cycle completed)")
    prefix = [_labels(scenario, n) for n in u]
    loop = [_labels(scenario, n) for n in v]
    by_lasso = holds(formula, prefix, loop)
    by_buchi = accepts_lasso(translate(formula), prefix, loop)
    entry.update({
        "word": [{"t": t, "region": name} for t, name in word],
        "cycles_completed": len(ends),
        "cycle_times": cycle_times,
        "cycle_time_mean": float(np.mean(cycle_times)) if cycle_times else None,
        "lasso": {"prefix": u, "loop": v, "closed_by": closed_by},
        "accepting": {"lasso": by_lasso, "buchi": by_buchi, "agree": by_lasso == by_buchi,
                      "met": by_lasso and by_buchi},
    })
    if by_lasso != by_buchi:
        entry["note"] = "the lasso evaluator and the Büchi automaton disagree: a bug to report"
    return entry


# ----------------------------------------------------------------------------------------------
# STL


def _stl_robot(scenario_name: str, robot_id: int, summary_entry: dict[str, Any],
               repair_events: list[dict[str, Any]]) -> dict[str, Any]:
    subtasks = []
    for index, sub in enumerate(summary_entry["subtasks"]):
        value = paper_values.lookup(scenario_name, robot_id, sub["task"])
        rho = _number_or_none(sub["robustness"])
        r_bar = _number_or_none(sub["r_last"])
        stages = list(sub["repairs_status"]) if isinstance(sub["repairs_status"], list) else []
        by_event = [sum(1 for e in repair_events if e["subtask"] == index and e["stage"] == s)
                    for s in (1, 2, 3)]
        paper = None
        if value is not None:
            paper = {"label": value.label, "printed": value.paper, "bound": value.bound,
                     "best": value.best, "best_note": value.best_note, "note": value.note,
                     "met": None if rho is None else rho >= value.bound,
                     "gap_to_best": None if rho is None or value.best is None
                     or not math.isfinite(rho) else rho - value.best}
        window = sub["window"]
        if window is None:
            try:
                phi = parse_task(sub["task"])
                window = [phi.a, phi.b]
            except TlfleetError:
                window = None
        subtasks.append({
            "index": index, "task": sub["task"], "op": sub["task"].lstrip()[:1],
            "window": window,
            "label": (paper_values.label(scenario_name, robot_id, sub["task"])
                      or f"r{robot_id}.{index + 1}"),
            "robustness": sub["robustness"], "r_bar": sub["r_last"],
            "robustness_ge_r_bar": None if rho is None or r_bar is None else rho >= r_bar,
            "repairs": {f"stage{s}": (stages[s - 1] if len(stages) >= s else None)
                        for s in (1, 2, 3)},
            "repair_events": {f"stage{s}": n for s, n in zip((1, 2, 3), by_event, strict=True)},
            "paper": paper,
        })
    return {"robustness": summary_entry["robustness"], "subtasks": subtasks,
            "repair_events": summary_entry["repair_events"], "error": summary_entry["error"]}


def _repair_events(events: list[dict[str, Any]]) -> dict[int, list[dict[str, Any]]]:
    """``repair`` events per agent: ``[{t, stage, subtask, r}]``."""
    out: dict[int, list[dict[str, Any]]] = {}
    for e in events:
        source = str(e.get("source", ""))
        if e.get("kind") not in ("repair", "recovery") or not source.startswith("agent/"):
            continue
        try:
            robot = int(source.split("/", 1)[1])
        except ValueError:
            continue
        data = e["data"]
        if e.get("kind") == "recovery" and isinstance(e.get("t"), (int, float)):
            out.setdefault(robot, []).append({
                "t": float(e["t"]), "stage": "recovery", "subtask": data.get("subtask"),
                "r": data.get("r") if isinstance(data.get("r"), (int, float)) else None})
            continue
        stage, t = data.get("stage"), e.get("t")
        if not isinstance(stage, int) or not isinstance(t, (int, float)):
            continue
        out.setdefault(robot, []).append({
            "t": float(t), "stage": stage, "subtask": data.get("subtask"),
            "r": data.get("r") if isinstance(data.get("r"), (int, float)) else None})
    return out


def stl_series(statuses: list[dict[str, str]], robot_id: int) -> dict[str, np.ndarray]:
    """Status rows of STL robot ``robot_id`` as arrays ``t, rho, rho_max, lower, r, subtask``
    (N,); empty cells (agent idle between sub-tasks) are NaN, a missing sub-task is −1."""
    rows = [row for row in statuses
            if row.get("kind") == "stl" and row.get("robot") == str(robot_id)]
    columns = ("t", "rho", "rho_max", "lower", "r", "subtask")
    out = {c: np.array([_cell(row.get(c)) for row in rows], dtype=float) for c in columns}
    out["subtask"] = np.where(np.isfinite(out["subtask"]), out["subtask"], -1.0)
    return out


# ----------------------------------------------------------------------------------------------
# the report


def trajectory_windows(scenario: Scenario, t_end: float) -> list[tuple[float, float]]:
    """Time windows of the trajectory figures [s]: split at the end ``b`` of every STL sub-task
    that another sub-task of the same robot follows (the phases of Fig. 5(a)/(b): Scenario 1 →
    [0, 30], [30, 90]); with no such boundary, the two halves. At most four windows."""
    splits: set[float] = set()
    for robot in scenario.robots:
        for text in robot.stl[:-1]:
            try:
                b = parse_task(text).b
            except TlfleetError:
                continue
            if 0 < b < t_end:
                splits.add(float(b))
    edges = [0.0, *sorted(splits)[:3], t_end] if splits else [0.0, t_end / 2, t_end]
    return [(a, b) for a, b in itertools.pairwise(edges) if b > a]


def figure_names(data: dict[str, Any]) -> list[str]:
    """The PNG files a report with ``data`` has (trajectory windows, then robustness per robot)."""
    names = [f"trajectories_{a:g}-{b:g}s.png" for a, b in data["figure_windows"]]
    names += [f"robustness_r{rid}.png" for rid in data["stl"]]
    return names


def _collect(run_dir: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """(report data, what the figures need) for ``run_dir``."""
    if not run_dir.is_dir():
        raise RunDirectoryError(run_dir, "not a run directory (does not exist or is not a folder)")
    scenario_path = run_dir / "scenario.toml"
    if not scenario_path.is_file():
        raise RunDirectoryError(scenario_path, "missing: a run directory holds the scenario.toml "
                                               "copy written by `tlfleet run`")
    files = read_run_files(run_dir)
    scenario, events, statuses, traj = files.scenario, files.events, files.statuses, files.traj
    skipped = files.skipped_event_lines
    _text, summary = summarise(files)
    run = summary["run"] or {}
    repairs = _repair_events(events)

    last_ltl: dict[int, dict[str, str]] = {}
    for row in statuses:
        if row.get("kind") == "ltl":
            try:
                last_ltl[int(row["robot"])] = row
            except (KeyError, ValueError):
                continue

    t_end = summary["t_end"] if traj is not None else scenario.duration
    data: dict[str, Any] = {
        "schema": SCHEMA,
        "scenario": scenario.name,
        "description": scenario.description,
        "run_dir": str(run_dir),
        "duration": scenario.duration,
        "mode": run.get("mode"),
        "frames": summary["frames"],
        "t_end": summary["t_end"],
        "trajectory_error": summary["trajectory_error"],
        "events_skipped_lines": skipped,
        "paper_note": paper_values.scenario_note(scenario.name),
        "stl": {str(rid): _stl_robot(scenario.name, rid, entry, repairs.get(rid, []))
                for rid, entry in summary["stl"].items()},
        "ltl": {str(rid): _ltl_robot(scenario, rid, traj, last_ltl.get(rid), entry)
                for rid, entry in summary["ltl"].items()},
        "contacts": summary["contacts"],
        "closest_approach": summary["closest_approach"],
        "timing": _timing(summary["deadlines"]),
        "process_deaths": summary["process_deaths"],
        "figure_windows": [list(w) for w in trajectory_windows(scenario, t_end)],
    }
    data["verdicts"] = verdicts.collect(scenario, traj, events, t_end, data["stl"])
    for rid, rows in data["verdicts"]["subtasks"].items():  # a window the run never closed
        for sub, row in zip(data["stl"][rid]["subtasks"], rows, strict=True):  # is not "met"
            if row["verdict"] == "not evaluated" and sub["paper"] is not None:
                sub["paper"]["met"] = None
    context = {"scenario": scenario, "traj": traj, "statuses": statuses, "repairs": repairs,
               "t_end": t_end if t_end > 0 else scenario.duration}
    return data, context


def _timing(deadlines: dict[str, Any]) -> dict[str, Any]:
    stats = deadlines.get("sim_stats") or {}
    return {
        "deadline_miss_events": deadlines["deadline_miss"],
        "deadline_miss_by_robot": deadlines["deadline_miss_by_robot"],
        "control_due": stats.get("due"),
        "control_missed": stats.get("missed"),
        "latency_p50_ms": stats.get("latency_p50_ms"),
        "latency_p99_ms": stats.get("latency_p99_ms"),
        "latency_max_ms": stats.get("latency_max_ms"),
        "watchdog_stop": deadlines["watchdog_stop"],
        "stale_mocap": deadlines["stale_mocap"],
        "malformed": deadlines["malformed"],
        "sim_stats_present": bool(stats),
    }


def build_report(run_dir: str | Path) -> Report:
    """The report of ``run_dir`` (reads its files, writes nothing); ``figures`` lists the report's
    PNG files already present in the directory."""
    run_dir = Path(run_dir)
    data, _context = _collect(run_dir)
    present = [run_dir / name for name in figure_names(data) if (run_dir / name).is_file()]
    return _finish(run_dir, data, present)


def write_report(run_dir: str | Path, *, figures: bool = True) -> Report:
    """Build the report of ``run_dir`` and write ``report.md``, ``report.json`` and (unless
    ``figures`` is false) the PNG figures into it."""
    run_dir = Path(run_dir)
    data, context = _collect(run_dir)
    written: list[Path] = []
    if figures:
        written = _write_figures(run_dir, data, context)
    else:
        written = [run_dir / name for name in figure_names(data) if (run_dir / name).is_file()]
    report = _finish(run_dir, data, written)
    (run_dir / "report.json").write_text(json.dumps(report.data, indent=2, ensure_ascii=False)
                                         + "\n", encoding="utf-8")
    (run_dir / "report.md").write_text(report.markdown, encoding="utf-8")
    return report


def _write_figures(run_dir: Path, data: dict[str, Any], context: dict[str, Any]) -> list[Path]:
    from coordinator import figures  # matplotlib only when figures are drawn

    scenario: Scenario = context["scenario"]
    written: list[Path] = []
    traj = context["traj"]
    if traj is not None:
        for a, b in data["figure_windows"]:
            path = run_dir / f"trajectories_{a:g}-{b:g}s.png"
            written.append(figures.trajectory_figure(scenario, traj, (a, b), path))
    for rid, entry in data["stl"].items():
        subtasks = [(s["label"], s["window"][0], s["window"][1]) for s in entry["subtasks"]
                    if s["window"] is not None]
        path = run_dir / f"robustness_r{rid}.png"
        written.append(figures.robustness_figure(
            int(rid), stl_series(context["statuses"], int(rid)), subtasks,
            context["repairs"].get(int(rid), []), path, t_end=context["t_end"]))
    return written


def _finish(run_dir: Path, data: dict[str, Any], figure_paths: list[Path]) -> Report:
    data = {**data, "figures": [p.name for p in figure_paths]}
    return Report(run_dir=run_dir, data=data, markdown=render_markdown(data),
                  table=render_table(data), figures=figure_paths)


# ----------------------------------------------------------------------------------------------
# rendering


def _fmt(value: Any, spec: str = "+.4f") -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)):
        return format(value, spec) if math.isfinite(value) else str(value)
    return str(value)


def _met(value: bool | None) -> str:
    return "–" if value is None else ("met" if value else "NOT met")


def _paper_text(paper: dict[str, Any] | None) -> str:
    """The printed bound, with the bound actually judged against when they differ."""
    if paper is None:
        return "–"
    printed = paper["printed"]
    return printed if paper["note"] == "" else f"{printed} → {paper['bound']:g}"


def _plan_text(plan: dict[str, Any]) -> str:
    return f"{' '.join(plan['prefix']) or '–'} ({' '.join(plan['suffix']) or '–'})ω"


def render_table(data: dict[str, Any]) -> str:
    """The short console table printed at the end of ``make run`` / by ``tlfleet report``."""
    lines = [f"report {data['scenario']}: t_end {data['t_end']:.2f} s, {data['frames']} frames"
             + (f", {data['mode']}" if data["mode"] else "")]
    if data["trajectory_error"]:
        lines.append(f"  trajectory: {data['trajectory_error']}")
    if data["stl"]:
        lines.append(f"  {'STL sub-task':<14}{'ours':>9}{'r̄':>9}{'paper':>19}{'best':>8}  met")
    for rid, entry in data["stl"].items():
        for s in entry["subtasks"]:
            p = s["paper"]
            label = (s["label"] if s["label"] == f"r{rid}.{s['index'] + 1}"
                     else f"{s['label']} (r{rid})")
            lines.append(f"  {label:<14}{_fmt(s['robustness']):>9}{_fmt(s['r_bar']):>9}"
                         f"{_paper_text(p):>19}"
                         f"{_fmt(p['best'], '+.2f') if p else '–':>8}  "
                         f"{_met(p['met']) if p else '–'}")
        if entry["error"]:
            lines.append(f"    ({entry['error']})")
    if data["stl"] and not any(s["paper"] for e in data["stl"].values() for s in e["subtasks"]):
        lines.append(f"  ({data['paper_note']})")
    for rid, entry in data["ltl"].items():
        visits = ", ".join(f"{n} {v['trajectory'] if v['trajectory'] is not None else v['agent']}"
                           for n, v in entry["visits"].items())
        mean = entry["cycle_time_mean"]
        cycles = f"cycles {entry['cycles_completed']}" + (
            f" (mean {mean:.1f} s)" if mean is not None else "")
        lines.append(f"  LTL r{rid} {entry['task']}: plan {_plan_text(entry['plan'])}; visits "
                     f"{visits}; {cycles}; accepting {_met(entry['accepting']['met'])}")
    c = data["contacts"]
    contacts = f"  contacts: robot-robot {c['robot_robot']}, robot-wall {c['robot_wall']}"
    ca = data["closest_approach"]
    if ca:
        contacts += f"; closest gap {ca['gap']:+.3f} m (r{ca['pair'][0]}-r{ca['pair'][1]}, " \
                    f"t {ca['t']:.2f} s)"
    lines.append(contacts)
    lines.append("  timing: " + _timing_text(data["timing"]))
    lines += ["  " + line for line in verdicts.render_lines(data["verdicts"])]
    return "\n".join(lines)


def _timing_text(timing: dict[str, Any]) -> str:
    parts = []
    if timing["control_due"]:
        parts.append(f"control deadlines missed {timing['control_missed'] or 0} of "
                     f"{timing['control_due']}")
    else:
        parts.append(f"deadline-miss events {timing['deadline_miss_events']} (no sim_stats)")
    if timing["latency_p50_ms"] is not None:
        parts.append(f"latency p50 {timing['latency_p50_ms']:.2f} ms, "
                     f"p99 {timing['latency_p99_ms']:.2f} ms")
    return ", ".join(parts)


def render_markdown(data: dict[str, Any]) -> str:
    """report.md: tables of the STL sub-tasks, LTL robots, contacts and timing; figure links."""
    out = [f"# Run report: {data['scenario']}", ""]
    if data["description"]:
        out += [data["description"], ""]
    out += [f"* run directory: `{data['run_dir']}`",
            f"* mode: {data['mode'] or '–'}; {data['frames']} frames; "
            f"t_end = {data['t_end']:.2f} s (scenario duration {data['duration']:g} s)"]
    if data["trajectory_error"]:
        out.append(f"* **trajectory unusable**: {data['trajectory_error']} — robustness, visits "
                   f"and figures from the trajectory are missing")
    if data["events_skipped_lines"]:
        out.append(f"* events.jsonl: line(s) {', '.join(map(str, data['events_skipped_lines']))} "
                   f"not JSON (torn write?), skipped")
    out.append("")

    out += ["## STL tasks", ""]
    if not data["stl"]:
        out += ["No STL robots.", ""]
    else:
        out += ["ρ: standard robustness (min/max semantics) from `trajectory.csv`; r̄: the bound "
                "the agent ended the sub-task with (ρ ≥ r̄ is the funnel's guarantee); repairs: the "
                "agent's counters per stage 1/2/3 (repair events in `events.jsonl`); met: ρ ≥ "
                "the paper's bound. Best: best achievable ρ (scenarios.md).", "",
                "| robot | label | sub-task | ρ | r̄ | ρ ≥ r̄ | repairs 1/2/3 (events) | paper | "
                "best | ρ − best | met |",
                "|---|---|---|---|---|---|---|---|---|---|---|"]
        notes = []
        for rid, entry in data["stl"].items():
            for s in entry["subtasks"]:
                p = s["paper"]
                rep = "/".join(_fmt(s["repairs"][f"stage{k}"], "d") for k in (1, 2, 3))
                ev = "/".join(str(s["repair_events"][f"stage{k}"]) for k in (1, 2, 3))
                out.append(
                    f"| {rid} | {s['label']} | `{s['task']}` | {_fmt(s['robustness'])} | "
                    f"{_fmt(s['r_bar'])} | {_fmt(s['robustness_ge_r_bar'])} | {rep} ({ev}) | "
                    f"{_paper_text(p)} | {_fmt(p['best'], '+.2f') if p else '–'} | "
                    f"{_fmt(p['gap_to_best']) if p else '–'} | {_met(p['met']) if p else '–'} |")
                if p and p["note"]:
                    notes.append(f"* {p['label']}: {p['note']}.")
                if p and p["best_note"] and p["best"] is None:
                    notes.append(f"* {p['label']}: best achievable {p['best_note']}.")
            if entry["error"]:
                notes.append(f"* robot {rid}: {entry['error']}")
        out.append("")
        if not any(s["paper"] for e in data["stl"].values() for s in e["subtasks"]):
            notes.append(f"* {data['paper_note']}.")
        out += [*notes, ""] if notes else []

    out += ["## LTL tasks", ""]
    if not data["ltl"]:
        out += ["No LTL robots.", ""]
    else:
        out += ["Word: region visits from the trajectory (disc entries with hysteresis, repeats "
                "collapsed; `start` = outside every region at t = 0). Cycle: the plan's suffix; "
                "a cycle is completed when the word runs through it back to its first region. "
                "The run is closed into the lasso u·v^ω with v = the last completed cycle (or the "
                "final region repeated when the task needs no cycle or none was completed) and "
                "checked with the exact lasso evaluator and the Büchi automaton "
                "(see `coordinator/report.py`).", "",
                "| robot | task | plan prefix (suffix)ω | visits agent/trajectory | cycles | "
                "cycle times [s] | mean [s] | lasso u · v^ω | lasso / Büchi | met |",
                "|---|---|---|---|---|---|---|---|---|---|"]
        for rid, e in data["ltl"].items():
            visits = ", ".join(f"{n} {v['agent']}/{_fmt(v['trajectory'], 'd')}"
                               for n, v in e["visits"].items())
            times = ", ".join(f"{x:.1f}" for x in e["cycle_times"]) or "–"
            lasso = (f"{' '.join(e['lasso']['prefix']) or 'ε'} · ({' '.join(e['lasso']['loop'])})ω"
                     if e["lasso"] else "–")
            acc = e["accepting"]
            out.append(f"| {rid} | `{e['task']}` | {_plan_text(e['plan'])} | {visits} | "
                       f"{e['cycles_completed']} | {times} | {_fmt(e['cycle_time_mean'], '.1f')} | "
                       f"{lasso} | {_fmt(acc['lasso'])} / {_fmt(acc['buchi'])} | "
                       f"{_met(acc['met'])} |")
        out.append("")
        for rid, e in data["ltl"].items():
            extra = [e["plan"]["source"]] + ([e["lasso"]["closed_by"]] if e["lasso"] else [])
            out.append(f"* robot {rid}: plan from {extra[0]}"
                       + (f"; lasso closed by the {extra[1]}" if len(extra) > 1 else "")
                       + (f"; **{e['note']}**" if e["note"] else "") + ".")
        out.append("")

    out += ["## Verdicts, coupling-aware limits and recovery", "",
            "Every STL sub-task: satisfied (ρ^φ > 0), violated by −ρ^φ, or not evaluated (the run "
            "ended before its window did); held = share of the window's samples with ρ^ψ ≥ 0. "
            "Coupling-aware leaders and robustness recovery go beyond the paper "
            "(docs/coupling.md).", ""]
    out += [f"* {line}" for line in verdicts.render_lines(data["verdicts"])] + [""]

    c, ca = data["contacts"], data["closest_approach"]
    out += ["## Contacts", "",
            f"robot–robot {c['robot_robot']}, robot–wall {c['robot_wall']}"
            + (f" ({', '.join(f'{k}: {v}' for k, v in sorted(c['pairs'].items()))})"
               if c["pairs"] else "") + ".",
            ""]
    if ca:
        out += [f"Closest approach: robots {ca['pair'][0]} and {ca['pair'][1]}, gap "
                f"{ca['gap']:+.3f} m (centre distance minus both radii) at t = {ca['t']:.2f} s.",
                ""]

    tm = data["timing"]
    out += ["## Timing", "",
            "| control deadlines due | missed | deadline-miss events | latency p50 [ms] | "
            "p99 [ms] | max [ms] | watchdog stops | stale mocap | malformed |",
            "|---|---|---|---|---|---|---|---|---|",
            f"| {_fmt(tm['control_due'], 'd')} | {_fmt(tm['control_missed'], 'd')} | "
            f"{tm['deadline_miss_events']} | {_fmt(tm['latency_p50_ms'], '.2f')} | "
            f"{_fmt(tm['latency_p99_ms'], '.2f')} | {_fmt(tm['latency_max_ms'], '.2f')} | "
            f"{tm['watchdog_stop']} | {tm['stale_mocap']} | {tm['malformed']} |", ""]
    if data["process_deaths"]:
        out += [f"Process deaths: {len(data['process_deaths'])}: "
                + "; ".join(f"{d.get('process')} at t = {_fmt(d.get('t'), '.2f')} s"
                            for d in data["process_deaths"]), ""]

    out += ["## Figures", ""]
    if data["figures"]:
        out += [f"![{name}]({name})" for name in data["figures"]]
        out += ["", "Trajectory windows: split at the ends of STL sub-tasks followed by another "
                "sub-task (else the two halves of the run); colour = time. Robustness: ρ^ψ(t) "
                "(solid), funnel ρ_max and lower = ρ_max − γ(t) (dashed), r (dotted), sub-task "
                "windows shaded, repairs marked by stage, recoveries by green triangles."]
    else:
        out.append("No figures written.")
    out.append("")
    return "\n".join(out)


# ----------------------------------------------------------------------------------------------
# small helpers


def _cell(text: str | None) -> float:
    try:
        return float(text) if text not in (None, "") else math.nan
    except ValueError:
        return math.nan


def _json_list(text: str | None) -> list[str]:
    try:
        value = json.loads(text) if text else []
    except json.JSONDecodeError:
        return []
    return [str(x) for x in value] if isinstance(value, list) else []


def _number_or_none(value: Any) -> float | None:
    """A summary number (float, or "inf"/"-inf" for an empty window) as a float; None if absent."""
    if isinstance(value, str) and value in ("inf", "-inf"):
        return float(value)
    if isinstance(value, (int, float)) and not isinstance(value, bool) and not math.isnan(value):
        return float(value)
    return None
