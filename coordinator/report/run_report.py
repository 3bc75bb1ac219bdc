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
from collections.abc import Iterable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from tlfleet.agent.model import Scenario
from tlfleet.agent.stl.monitor import Trajectory
from tlfleet.agent.stl.parser import robot_subtasks
from tlfleet.bus.protocol.messages import LtlStatus, StlStatus
from tlfleet.coordinator.record import rundir
from tlfleet.coordinator.record.run_record import (
    Deadlines,
    LostFrames,
    Report,
    RunSummary,
    StlRobotReport,
    SubtaskVerdict,
    TaskTally,
    Timing,
    write_record,
)
from tlfleet.coordinator.record.rundir import RunDirectoryError, RunFiles
from tlfleet.coordinator.report import paper_values, task_verdicts
from tlfleet.coordinator.report.fault_table import fault_rows
from tlfleet.coordinator.report.ltl_words import ltl_robot_report
from tlfleet.coordinator.report.paper_comparison import (
    RepairEvent,
    repair_events,
    stl_robot_report,
)
from tlfleet.coordinator.report.render import render_markdown
from tlfleet.coordinator.report.summary import summarise
from tlfleet.coordinator.report.task_tally import task_tally

__all__ = ["Report", "RunDirectoryError", "build_report", "write_report"]


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


def figure_names(report: Report, fmt: str = "png") -> list[str]:
    """The figure files ``report`` has in format ``fmt`` (trajectory windows, then robustness per
    robot)."""
    names = [f"trajectories_{a:g}-{b:g}s.{fmt}" for a, b in report.figure_windows]
    names += [f"robustness_r{rid}.{fmt}" for rid in report.stl]
    return names


def _present_figures(report: Report) -> tuple[str, ...]:
    """The report's figures already in its run directory, whatever their format."""
    from tlfleet.coordinator.report.figures import FORMATS

    return tuple(name for fmt in FORMATS for name in figure_names(report, fmt)
                 if (report.run_dir / name).is_file())


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


def _collect(files: RunFiles, summary: RunSummary | None = None,
             tally: TaskTally | None = None) -> tuple[Report, dict[int, list[RepairEvent]]]:
    """The report (no figures yet) from the files read once, their summary and task tally
    (each computed here when not given), and the repair events the figures mark."""
    scenario, events, statuses, traj = (files.scenario, files.events, files.statuses,
                                        files.trajectory)
    if summary is None:
        _text, summary = summarise(files)
    repairs = repair_events(events)
    last_ltl = {s.robot: s for s in statuses if isinstance(s, LtlStatus)}
    t_end = summary.t_end if traj is not None else scenario.duration
    stl = {rid: stl_robot_report(scenario.name, rid, entry, repairs.get(rid, []))
           for rid, entry in summary.stl.items()}
    verdicts = task_verdicts.collect(scenario, traj, events, t_end, stl)
    stl = {rid: _unevaluated_not_met(entry, verdicts.subtasks[rid]) for rid, entry in stl.items()}
    report = Report(
        scenario=scenario.name,
        description=scenario.description,
        run_dir=files.run_dir,
        duration=scenario.duration,
        mode=summary.mode,
        frames=summary.frames,
        t_end=summary.t_end,
        trajectory_error=summary.trajectory_error,
        events_skipped_lines=tuple(files.skipped_event_lines),
        paper_note=paper_values.scenario_note(scenario.name),
        stl=stl,
        ltl={rid: ltl_robot_report(scenario, rid, traj, last_ltl.get(rid), entry)
             for rid, entry in summary.ltl.items()},
        contacts=summary.contacts,
        closest_approach=summary.closest_approach,
        timing=_timing(summary.deadlines),
        process_deaths=summary.process_deaths,
        faults=tuple(fault_rows(scenario, events, traj)),
        figure_windows=tuple(trajectory_windows(scenario, t_end)),
        verdicts=verdicts,
        tasks=tally or task_tally(files, summary),
        lost_frames=lost_frames(traj, float(files.info.get("duration", scenario.duration)),
                                scenario.sim.mocap_rate))
    return report, repairs


def lost_frames(traj: Trajectory | None, duration: float, rate: float,
                gap: float = 1.5) -> tuple[LostFrames, ...]:
    """The stretches of sim time ``trajectory.csv`` has no frame for, read off the file itself:
    a gap between two rows longer than ``gap`` mocap periods, and the end of the run (its
    ``duration`` [s]) when the last row falls short of it — frames lost on a link and never
    backfilled, or the end of a run whose simulator the coordinator lost."""
    if traj is None or len(traj.t) == 0:
        return ()
    period = 1.0 / rate
    t = np.asarray(traj.t)
    out = [LostFrames(float(t[k]), float(t[k + 1]), round(float(t[k + 1] - t[k]) / period) - 1)
           for k in np.flatnonzero(np.diff(t) > gap * period)]
    if t[-1] < duration - gap * period:
        out.append(LostFrames(float(t[-1]), float(duration),
                              round((duration - float(t[-1])) / period)))
    return tuple(out)


def _unevaluated_not_met(entry: StlRobotReport, rows: tuple[SubtaskVerdict, ...]
                         ) -> StlRobotReport:
    """A sub-task whose window the run never closed is not "met" against the paper either."""
    subtasks = tuple(
        replace(sub, paper=replace(sub.paper, met=None))
        if row.verdict == "not evaluated" and sub.paper is not None else sub
        for sub, row in zip(entry.subtasks, rows, strict=True))
    return replace(entry, subtasks=subtasks)


def _timing(deadlines: Deadlines) -> Timing:
    stats = deadlines.sim_stats
    return Timing(
        deadline_miss_events=deadlines.deadline_miss,
        deadline_miss_by_robot=deadlines.deadline_miss_by_robot,
        control_due=stats.due if stats and "due" in stats.counters else None,
        control_missed=stats.missed if stats and "missed" in stats.counters else None,
        latency_p50_ms=stats.latency_p50_ms if stats else None,
        latency_p99_ms=stats.latency_p99_ms if stats else None,
        latency_max_ms=stats.latency_max_ms if stats else None,
        watchdog_stop=deadlines.watchdog_stop,
        stale_mocap=deadlines.stale_mocap,
        malformed=deadlines.malformed,
        sim_stats_present=bool(stats and stats.counters))


def build_report(run: RunFiles | str | Path, summary: RunSummary | None = None,
                 tally: TaskTally | None = None) -> Report:
    """The report of a run directory (its files as read by :func:`rundir.read_run`, or its path;
    writes nothing); ``figures`` names the report's figures already present in it."""
    files = run if isinstance(run, RunFiles) else rundir.read_run(run)
    report, _repairs = _collect(files, summary, tally)
    return replace(report, figures=_present_figures(report))


def write_report(run: RunFiles | str | Path, *, figures: bool = True,
                 summary: RunSummary | None = None, tally: TaskTally | None = None,
                 figure_format: str = "png") -> Report:
    """Build the report of a run directory (files read once, or its path; ``summary`` when the
    caller computed it already) and write ``report.md``, ``report.json`` and (unless ``figures``
    is false) the figures into it, as ``figure_format`` (png, pdf or svg)."""
    files = run if isinstance(run, RunFiles) else rundir.read_run(run)
    run_dir = files.run_dir
    report, repairs = _collect(files, summary, tally)
    if figures:
        try:
            written = _write_figures(report, files, repairs, figure_format)
        except OSError as exc:
            raise RunDirectoryError(Path(exc.filename or run_dir),
                                    f"cannot write a figure: {exc.strerror}") from None
    else:
        written = _present_figures(report)
    report = replace(report, figures=written)
    for name, write in ((rundir.REPORT_JSON, lambda p: write_record(p, report)),
                        (rundir.REPORT_MD, lambda p: p.write_text(render_markdown(report),
                                                                  encoding="utf-8"))):
        try:
            write(run_dir / name)
        except OSError as exc:  # a directory in its place, a read-only run directory
            raise RunDirectoryError(run_dir / name, f"cannot write: {exc.strerror}") from None
    return report


def _write_figures(report: Report, files: RunFiles, repairs: Mapping[int, list[RepairEvent]],
                   fmt: str = "png") -> tuple[str, ...]:
    from tlfleet.coordinator.report import figures  # matplotlib only when figures are drawn

    if fmt not in figures.FORMATS:
        raise ValueError(f"figure format {fmt!r}: expected one of {', '.join(figures.FORMATS)}")
    scenario, traj, run_dir = files.scenario, files.trajectory, report.run_dir
    t_end = report.t_end if traj is not None else scenario.duration
    written: list[Path] = []
    if traj is not None:
        for a, b in report.figure_windows:
            path = run_dir / f"trajectories_{a:g}-{b:g}s.{fmt}"
            written.append(figures.trajectory_figure(scenario, traj, (a, b), path,
                                                     goals=stl_goals(scenario, (a, b))))
    for rid, entry in report.stl.items():
        subtasks = [(s.label, s.window[0], s.window[1]) for s in entry.subtasks
                    if s.window is not None]
        path = run_dir / f"robustness_r{rid}.{fmt}"
        written.append(figures.robustness_figure(
            rid, stl_series(files.statuses, rid), subtasks, repairs.get(rid, []), path,
            t_end=t_end if t_end > 0 else scenario.duration))
    return tuple(p.name for p in written)
