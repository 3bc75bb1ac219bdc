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

from dataclasses import dataclass
from typing import Any, Literal

from tlfleet.agent.model import Scenario
from tlfleet.bus.protocol.messages import LtlStatus
from tlfleet.coordinator.record.rundir import RunFiles
from tlfleet.coordinator.report import paper_values
from tlfleet.coordinator.report.ltl_words import ltl_robot_report
from tlfleet.coordinator.report.task_verdicts import verdict

#: exit code of ``tlfleet run --require-tasks`` when the fleet ran but a task was not met
TASKS_NOT_MET = 5

Outcome = Literal["met", "not met", "violated", "not evaluated"]


@dataclass(frozen=True)
class TaskResult:
    """One task of one robot: ``label`` (``LTL``, the paper's name of an STL sub-task or
    ``stl[k]``), the task's text, the outcome and, for a violated STL sub-task, by how much
    (``by`` = −ρ)."""

    robot: int
    label: str
    task: str
    outcome: Outcome
    by: float | None = None
    reason: str = ""

    @property
    def met(self) -> bool:
        return self.outcome == "met"

    @property
    def text(self) -> str:
        """``robot 8 stl[1] violated by 0.860``."""
        what = f"violated by {self.by:.3f}" if self.outcome == "violated" else self.outcome
        return f"robot {self.robot} {self.label} {what}"

    def to_json(self) -> dict[str, Any]:
        return {"robot": self.robot, "label": self.label, "task": self.task,
                "outcome": self.outcome, "met": self.met, "by": self.by, "reason": self.reason}


@dataclass(frozen=True)
class TaskTally:
    """Every task's result, robots in id order, an LTL robot's task before nothing and an STL
    robot's sub-tasks in order."""

    results: tuple[TaskResult, ...]

    @property
    def met(self) -> int:
        return sum(r.met for r in self.results)

    @property
    def total(self) -> int:
        return len(self.results)

    @property
    def all_met(self) -> bool:
        return self.met == self.total

    @property
    def line(self) -> str:
        """``tasks: 5 of 7 met; robot 3 LTL not met, robot 8 stl[1] violated by 0.860``."""
        head = f"tasks: {self.met} of {self.total} met"
        missed = [r.text for r in self.results if not r.met]
        return head + (f"; {', '.join(missed)}" if missed else "")

    def to_json(self) -> dict[str, Any]:
        return {"met": self.met, "total": self.total, "all_met": self.all_met,
                "line": self.line, "results": [r.to_json() for r in self.results]}


def stl_label(scenario: Scenario, robot: int, index: int, task: str) -> str:
    """The paper's name of a sub-task of its scenarios (``φ′3``), else ``stl[index]`` (the
    scenario file's field)."""
    return paper_values.label(scenario.name, robot, task) or f"stl[{index}]"


def task_tally(files: RunFiles, summary: dict[str, Any]) -> TaskTally:
    """The tally of a run directory's files (read once, :func:`rundir.read_run`) and their
    summary (:func:`tlfleet.coordinator.report.summary.summarise`)."""
    scenario, traj = files.scenario, files.trajectory
    t_end = float(summary["t_end"]) if traj is not None else 0.0
    last_ltl = {s.robot: s for s in files.statuses if isinstance(s, LtlStatus)}
    results: list[TaskResult] = []
    for robot in sorted(scenario.robots, key=lambda r: r.id):
        if robot.is_ltl:
            entry = summary["ltl"].get(robot.id)
            report = (ltl_robot_report(scenario, robot.id, traj, last_ltl.get(robot.id), entry)
                      if entry is not None else None)
            met = bool(report and report["accepting"]["met"])
            note = report["note"] if report else "no summary of this robot"
            if report and report["note"].startswith("no trajectory"):
                results.append(TaskResult(robot.id, "LTL", robot.ltl or "", "not evaluated",
                                          reason=note))
                continue
            results.append(TaskResult(robot.id, "LTL", robot.ltl or "",
                                      "met" if met else "not met", reason="" if met else (
                                          note or "the executed word does not satisfy it")))
            continue
        entry = summary["stl"].get(robot.id) or {"subtasks": []}
        subtasks = entry["subtasks"] or [{"task": t, "window": None, "robustness": None}
                                         for t in robot.stl]
        for index, sub in enumerate(subtasks):
            label = stl_label(scenario, robot.id, index, sub["task"])
            window, rho = sub["window"], sub["robustness"]
            if window is None or traj is None:
                results.append(TaskResult(robot.id, label, sub["task"], "not evaluated",
                                          reason="no trajectory"))
                continue
            row = verdict(sub["task"].lstrip()[:1], window[0], window[1],
                          None if rho is None else float(rho), t_end)
            outcome: Outcome = {"satisfied": "met", "violated": "violated"}.get(
                row["verdict"], "not evaluated")  # type: ignore[assignment]
            results.append(TaskResult(robot.id, label, sub["task"], outcome, row["by"],
                                      row["reason"]))
    return TaskTally(tuple(results))
