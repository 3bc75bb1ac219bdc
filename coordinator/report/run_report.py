"""The run report: ``report.md``, ``report.json`` and figures of a run (architecture.md §6).

:func:`build_report` takes a run directory's files as read once by
:func:`tlfleet.coordinator.record.rundir.read_run` (``scenario.toml`` required; ``trajectory.csv``,
``status.csv``, ``events.jsonl``, ``run.json`` optional) and returns a :class:`Report`;
:func:`write_report` also writes ``report.md``, ``report.json`` and the PNG figures
(``tlfleet.coordinator.report.figures``). It builds on the summary
(:func:`tlfleet.coordinator.report.summary.summarise`, computed once per command) and adds, per
concern, in its own module:

* STL sub-tasks beside the paper's values — :mod:`tlfleet.coordinator.report.paper_comparison`;
* LTL robots' executed words, cycles and accepting condition —
  :mod:`tlfleet.coordinator.report.ltl_words`;
* the console table and ``report.md`` — :mod:`tlfleet.coordinator.report.render`.

Everything else (contacts, closest approach, deadline and latency statistics from ``sim_stats``,
process deaths) is the summary's.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tlfleet.agent.model import Scenario
from tlfleet.agent.stl.parser import robot_subtasks
from tlfleet.bus.protocol.messages import LtlStatus, StlStatus
from tlfleet.coordinator.record import rundir
from tlfleet.coordinator.record.rundir import RunDirectoryError, RunFiles
from tlfleet.coordinator.report import paper_values, task_verdicts
from tlfleet.coordinator.report.fault_table import fault_rows
from tlfleet.coordinator.report.ltl_words import ltl_robot_report
from tlfleet.coordinator.report.paper_comparison import repair_events, stl_robot_report
from tlfleet.coordinator.report.render import render_markdown, render_table
from tlfleet.coordinator.report.summary import summarise
from tlfleet.coordinator.report.task_tally import TaskTally, task_tally

__all__ = ["Report", "RunDirectoryError", "build_report", "write_report"]

SCHEMA = 3  # 3: "tasks", the task tally; 2: r_bar is the least r in force (was the last
#            status r, now r_final)


@dataclass
class Report:
    """A run's report: ``data`` is report.json, ``markdown`` report.md, ``table`` the console
    table, ``figures`` the PNG files (written, or already present for :func:`build_report`)."""

    run_dir: Path
    data: dict[str, Any]
    markdown: str
    table: str
    figures: list[Path] = field(default_factory=list)


def stl_series(statuses: Iterable[LtlStatus | StlStatus], robot_id: int
               ) -> dict[str, np.ndarray]:
    """Statuses of STL robot ``robot_id`` as arrays ``t, rho, rho_max, lower, r, subtask``
    (N,); NaN where the agent is idle between sub-tasks."""
    rows = [s for s in statuses if isinstance(s, StlStatus) and s.robot == robot_id]
    columns = ("t", "rho", "rho_max", "lower", "r", "subtask")
    return {c: np.array([float(getattr(s, c)) for s in rows], dtype=float) for c in columns}


# ----------------------------------------------------------------------------------------------
# the report


def trajectory_windows(scenario: Scenario, t_end: float) -> list[tuple[float, float]]:
    """Time windows of the trajectory figures [s]: split at the end ``b`` of every STL sub-task
    that another sub-task of the same robot follows (the phases of Fig. 5(a)/(b): Scenario 1 →
    [0, 30], [30, 90]); with no such boundary, the two halves. At most four windows."""
    splits: set[float] = set()
    for robot in scenario.robots:
        for tree in robot_subtasks(robot)[:-1]:
            b = tree.b
            if 0 < b < t_end:
                splits.add(float(b))
    edges = [0.0, *sorted(splits)[:3], t_end] if splits else [0.0, t_end / 2, t_end]
    return [(a, b) for a, b in itertools.pairwise(edges) if b > a]


def figure_names(data: dict[str, Any], fmt: str = "png") -> list[str]:
    """The figure files a report with ``data`` has in format ``fmt`` (trajectory windows, then
    robustness per robot)."""
    names = [f"trajectories_{a:g}-{b:g}s.{fmt}" for a, b in data["figure_windows"]]
    names += [f"robustness_r{rid}.{fmt}" for rid in data["stl"]]
    return names


def _present_figures(run_dir: Path, data: dict[str, Any]) -> list[Path]:
    """The report's figures already in ``run_dir``, whatever their format."""
    from tlfleet.coordinator.report.figures import FORMATS

    return [run_dir / name for fmt in FORMATS for name in figure_names(data, fmt)
            if (run_dir / name).is_file()]


def stl_goals(scenario: Scenario, window: tuple[float, float]
              ) -> list[tuple[int, float, float, float]]:
    """The STL goal points of the sub-tasks active in ``window`` [s] (sharing more than an
    instant with it), as ``(i, x, y, c)``: what the trajectory figures mark (× and the tolerance
    circle)."""
    a, b = window
    out: list[tuple[int, float, float, float]] = []
    for _robot, start, end, goal in subtask_goals(scenario):
        if start < b and end > a and goal not in out:
            out.append(goal)
    return out


def subtask_goals(scenario: Scenario
                  ) -> list[tuple[int, float, float, tuple[int, float, float, float]]]:
    """Every STL sub-task's goal points: each predicate ``dist(p_i, [x, y]) <= c`` (or ``<``)
    with constants x, y, c [m], as ``(robot, a, b, (i, x, y, c))`` with the sub-task's window
    [a, b] [s]."""
    from tlfleet.agent.stl import syntax as stl

    def constant(expr: Any) -> float | None:
        if isinstance(expr, stl.Const):
            return float(expr.value)
        if isinstance(expr, stl.Neg):
            inner = constant(expr.arg)
            return None if inner is None else -inner
        return None

    def goals_of(node: Any) -> list[tuple[int, float, float, float]]:
        if isinstance(node, stl.And):
            return [g for child in node.children for g in goals_of(child)]
        if not isinstance(node, stl.Predicate) or node.cmp not in ("<=", "<"):
            return []
        lhs, tolerance = node.lhs, constant(node.rhs)
        if not (isinstance(lhs, stl.Call) and lhs.func == "dist" and tolerance is not None):
            return []
        found = []
        for own, other in (lhs.args, lhs.args[::-1]):
            if isinstance(own, stl.Position) and isinstance(other, stl.VecLit):
                x, y = constant(other.x), constant(other.y)
                if x is not None and y is not None:
                    found.append((own.robot, x, y, tolerance))
        return found

    return [(robot.id, tree.a, tree.b, goal) for robot in scenario.robots
            for tree in robot_subtasks(robot) for goal in goals_of(tree.body)]


def _collect(files: RunFiles, summary: dict[str, Any] | None = None,
             tally: TaskTally | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
    """(report data, what the figures need) from the files read once, their summary and task
    tally (each computed here when not given)."""
    run_dir = files.run_dir
    scenario, events, statuses, traj = (files.scenario, files.events, files.statuses,
                                        files.trajectory)
    skipped = files.skipped_event_lines
    if summary is None:
        _text, summary = summarise(files)
    run = summary["run"] or {}
    repairs = repair_events(events)
    last_ltl = {s.robot: s for s in statuses if isinstance(s, LtlStatus)}

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
        "stl": {str(rid): stl_robot_report(scenario.name, rid, entry, repairs.get(rid, []))
                for rid, entry in summary["stl"].items()},
        "ltl": {str(rid): ltl_robot_report(scenario, rid, traj, last_ltl.get(rid), entry)
                for rid, entry in summary["ltl"].items()},
        "contacts": summary["contacts"],
        "closest_approach": summary["closest_approach"],
        "timing": _timing(summary["deadlines"]),
        "process_deaths": summary["process_deaths"],
        "faults": fault_rows(scenario, events, traj),
        "figure_windows": [list(w) for w in trajectory_windows(scenario, t_end)],
    }
    data["verdicts"] = task_verdicts.collect(scenario, traj, events, t_end, data["stl"])
    for rid, rows in data["verdicts"]["subtasks"].items():  # a window the run never closed
        for sub, row in zip(data["stl"][rid]["subtasks"], rows, strict=True):  # is not "met"
            if row["verdict"] == "not evaluated" and sub["paper"] is not None:
                sub["paper"]["met"] = None
    data["tasks"] = (tally or task_tally(files, summary)).to_json()
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


def build_report(run: RunFiles | str | Path, summary: dict[str, Any] | None = None,
                 tally: TaskTally | None = None) -> Report:
    """The report of a run directory (its files as read by :func:`rundir.read_run`, or its path;
    writes nothing); ``figures`` lists the report's PNG files already present in it."""
    files = run if isinstance(run, RunFiles) else rundir.read_run(run)
    data, _context = _collect(files, summary, tally)
    return _finish(files.run_dir, data, _present_figures(files.run_dir, data))


def write_report(run: RunFiles | str | Path, *, figures: bool = True,
                 summary: dict[str, Any] | None = None, tally: TaskTally | None = None,
                 figure_format: str = "png") -> Report:
    """Build the report of a run directory (files read once, or its path; ``summary`` when the
    caller computed it already) and write ``report.md``, ``report.json`` and (unless ``figures``
    is false) the figures into it, as ``figure_format`` (png, pdf or svg)."""
    files = run if isinstance(run, RunFiles) else rundir.read_run(run)
    run_dir = files.run_dir
    data, context = _collect(files, summary, tally)
    written: list[Path] = []
    if figures:
        try:
            written = _write_figures(run_dir, data, context, figure_format)
        except OSError as exc:
            raise RunDirectoryError(Path(exc.filename or run_dir),
                                    f"cannot write a figure: {exc.strerror}") from None
    else:
        written = _present_figures(run_dir, data)
    report = _finish(run_dir, data, written)
    for name, write in ((rundir.REPORT_JSON, lambda p: rundir.write_json(p, report.data)),
                        (rundir.REPORT_MD, lambda p: p.write_text(report.markdown,
                                                                  encoding="utf-8"))):
        try:
            write(run_dir / name)
        except OSError as exc:  # a directory in its place, a read-only run directory
            raise RunDirectoryError(run_dir / name, f"cannot write: {exc.strerror}") from None
    return report


def _write_figures(run_dir: Path, data: dict[str, Any], context: dict[str, Any],
                   fmt: str = "png") -> list[Path]:
    from tlfleet.coordinator.report import figures  # matplotlib only when figures are drawn

    if fmt not in figures.FORMATS:
        raise ValueError(f"figure format {fmt!r}: expected one of {', '.join(figures.FORMATS)}")
    scenario: Scenario = context["scenario"]
    written: list[Path] = []
    traj = context["traj"]
    if traj is not None:
        for a, b in data["figure_windows"]:
            path = run_dir / f"trajectories_{a:g}-{b:g}s.{fmt}"
            written.append(figures.trajectory_figure(scenario, traj, (a, b), path,
                                                     goals=stl_goals(scenario, (a, b))))
    for rid, entry in data["stl"].items():
        subtasks = [(s["label"], s["window"][0], s["window"][1]) for s in entry["subtasks"]
                    if s["window"] is not None]
        path = run_dir / f"robustness_r{rid}.{fmt}"
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
