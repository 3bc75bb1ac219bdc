"""STL robots in the run report, beside the paper's reported values.

**STL sub-tasks.** Beside the standard robustness ρ (min/max semantics, from the trajectory),
the guaranteed bound r̄ (``r_bar``: the least r in force over the sub-task, so ρ^φ ≥ r̄; see
``tlfleet.coordinator.report.summary``) and the final funnel's r (``r_final``, above r̄ after a
recovery), the paper's reported lower bound and the best achievable value
(``tlfleet.coordinator.report.paper_values``, matched by scenario name *and* canonical sub-task
text) with ``met`` ⇔ ρ ≥ bound, and ``gap_to_best`` = ρ − best. Repairs per stage come from the
agent's counters (last status row of the sub-task) and from ``repair`` events (``data.subtask``,
``data.stage``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

from tlfleet.agent.stl.parser import parse_task
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.protocol.messages import Event
from tlfleet.coordinator.record.run_record import (
    PaperComparison,
    StageCounts,
    StlRobotReport,
    StlRobotSummary,
    StlSubtaskReport,
)
from tlfleet.coordinator.report import paper_values


@dataclass(frozen=True)
class RepairEvent:
    """A ``repair`` event of an agent (``stage`` 1–3) or a ``recovery`` (stage "recovery"), at
    sim time ``t`` [s], with the r it set (None: the event carries none)."""

    t: float  # [s]
    stage: int | Literal["recovery"]
    subtask: int | None
    r: float | None


def stl_robot_report(scenario_name: str, robot_id: int, summary: StlRobotSummary,
                     repair_events: Sequence[RepairEvent]) -> StlRobotReport:
    """The report entry of STL robot ``robot_id``: per sub-task ρ, r̄, repairs and the paper's
    values beside them (module docstring)."""
    subtasks = []
    for index, sub in enumerate(summary.subtasks):
        value = paper_values.lookup(scenario_name, robot_id, sub.task)
        rho = sub.robustness  # float (±inf: empty window) or None (not evaluated)
        r_bar = sub.r_least
        stages = list(sub.repairs_status)
        by_event = [sum(1 for e in repair_events if e.subtask == index and e.stage == s)
                    for s in (1, 2, 3)]
        paper = None
        if value is not None:
            paper = PaperComparison(
                label=value.label, printed=value.paper, bound=value.bound, best=value.best,
                best_note=value.best_note, note=value.note,
                met=None if rho is None else rho >= value.bound,
                gap_to_best=None if rho is None or value.best is None
                or not math.isfinite(rho) else rho - value.best)
        window = sub.window
        if window is None:
            try:
                phi = parse_task(sub.task)
                window = (phi.a, phi.b)
            except TlfleetError:
                window = None
        subtasks.append(StlSubtaskReport(
            index=index, task=sub.task, op=sub.task.lstrip()[:1], window=window,
            label=(paper_values.label(scenario_name, robot_id, sub.task)
                   or f"r{robot_id}.{index + 1}"),
            robustness=sub.robustness, r_bar=r_bar, r_final=sub.r_last,
            robustness_ge_r_bar=None if rho is None or r_bar is None else rho >= r_bar,
            repairs=StageCounts(*(stages[s - 1] if len(stages) >= s else None
                                  for s in (1, 2, 3))),
            repair_events=StageCounts(*by_event),
            paper=paper))
    return StlRobotReport(robustness=summary.robustness, subtasks=tuple(subtasks),
                          repair_events=summary.repair_events, error=summary.error)


def repair_events(events: Iterable[Event]) -> dict[int, list[RepairEvent]]:
    """``repair`` (and ``recovery``: stage "recovery") events per agent."""
    out: dict[int, list[RepairEvent]] = {}
    for e in events:
        head, _, tail = e.source.partition("/")
        if e.kind not in ("repair", "recovery") or head != "agent" or not tail.isdigit():
            continue
        data = e.data
        subtask = data.get("subtask")
        subtask = subtask if isinstance(subtask, int) and not isinstance(subtask, bool) else None
        r = data.get("r")
        r = float(r) if isinstance(r, int | float) and not isinstance(r, bool) else None
        if e.kind == "recovery":
            out.setdefault(int(tail), []).append(RepairEvent(e.t, "recovery", subtask, r))
            continue
        stage = data.get("stage")
        if not isinstance(stage, int):
            continue
        out.setdefault(int(tail), []).append(RepairEvent(e.t, stage, subtask, r))
    return out
