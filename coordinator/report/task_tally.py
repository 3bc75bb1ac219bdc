"""The task verdict of a run: which tasks were met, counted (README "Exit codes").

The process verdict (:mod:`tlfleet.coordinator.live.verdict`: clean, degraded, failed) says how
the fleet ran; this says what it achieved. Every task of the scenario is one row:

* an **LTL task** is met when the word the robot's trajectory produced satisfies it
  (:func:`tlfleet.coordinator.report.ltl_words.ltl_robot_report`: the executed lasso, checked by
  the exact evaluator and the Büchi automaton);
* an **STL sub-task** is met when its robustness, recomputed from the trajectory, is positive
  over a window the run covered (:func:`tlfleet.coordinator.report.task_verdicts.verdict`);
  ``violated by x`` (x = −ρ ≥ 0) otherwise, and ``not evaluated`` when the run ended before the
  window closed — which is not met either: nothing shows it was.

:attr:`TaskTally.line` is the last line but one of every run (``tasks: 5 of 7 met; robot 3 LTL
not met, robot 8 stl[1] violated by 0.860``); ``tlfleet run --require-tasks`` exits
:data:`TASKS_NOT_MET` when a task is not met. ``run.json`` and ``report.json`` carry
:meth:`TaskTally.to_json` under ``tasks``.
"""

from __future__ import annotations

from tlfleet.agent.model import Scenario
from tlfleet.bus.protocol.messages import LtlStatus
from tlfleet.coordinator.record.run_record import (
    Outcome,
    RunSummary,
    StlSubtaskSummary,
    TaskResult,
    TaskTally,
)
from tlfleet.coordinator.record.rundir import RunFiles
from tlfleet.coordinator.report import paper_values
from tlfleet.coordinator.report.ltl_words import ltl_robot_report
from tlfleet.coordinator.report.task_verdicts import verdict

#: exit code of ``tlfleet run --require-tasks`` when the fleet ran but a task was not met
TASKS_NOT_MET = 5

__all__ = ["TASKS_NOT_MET", "Outcome", "TaskResult", "TaskTally", "stl_label", "task_tally"]


def stl_label(scenario: Scenario, robot: int, index: int, task: str) -> str:
    """The paper's name of a sub-task of its scenarios (``φ′3``), else ``stl[index]`` (the
    scenario file's field)."""
    return paper_values.label(scenario.name, robot, task) or f"stl[{index}]"


def task_tally(files: RunFiles, summary: RunSummary) -> TaskTally:
    """The tally of a run directory's files (read once, :func:`rundir.read_run`) and their
    summary (:func:`tlfleet.coordinator.report.summary.summarise`)."""
    scenario, traj = files.scenario, files.trajectory
    t_end = float(summary.t_end) if traj is not None else 0.0
    last_ltl = {s.robot: s for s in files.statuses if isinstance(s, LtlStatus)}
    results: list[TaskResult] = []
    for robot in sorted(scenario.robots, key=lambda r: r.id):
        if robot.is_ltl:
            ltl = summary.ltl.get(robot.id)
            report = (ltl_robot_report(scenario, robot.id, traj, last_ltl.get(robot.id), ltl)
                      if ltl is not None else None)
            met = bool(report and report.accepting.met)
            note = report.note if report else "no summary of this robot"
            if report and report.note.startswith("no trajectory"):
                results.append(TaskResult(robot.id, "LTL", robot.ltl or "", "not evaluated",
                                          reason=note))
                continue
            results.append(TaskResult(robot.id, "LTL", robot.ltl or "",
                                      "met" if met else "not met", reason="" if met else (
                                          note or "the executed word does not satisfy it")))
            continue
        stl = summary.stl.get(robot.id)
        subtasks = (stl.subtasks if stl is not None and stl.subtasks else
                    [StlSubtaskSummary(t, None, None, None, None, ()) for t in robot.stl])
        for index, sub in enumerate(subtasks):
            label = stl_label(scenario, robot.id, index, sub.task)
            window, rho = sub.window, sub.robustness
            if window is None or traj is None:
                results.append(TaskResult(robot.id, label, sub.task, "not evaluated",
                                          reason="no trajectory"))
                continue
            row = verdict(sub.task.lstrip()[:1], window[0], window[1], rho, t_end)
            outcome: Outcome = ("met" if row.verdict == "satisfied" else
                                "violated" if row.verdict == "violated" else "not evaluated")
            results.append(TaskResult(robot.id, label, sub.task, outcome, row.by, row.reason))
    return TaskTally(tuple(results))
