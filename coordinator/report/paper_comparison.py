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
from collections.abc import Iterable
from typing import Any

from tlfleet.agent.stl.parser import parse_task
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.protocol.messages import Event
from tlfleet.coordinator.report import paper_values


def stl_robot_report(scenario_name: str, robot_id: int, summary_entry: dict[str, Any],
                     repair_events: list[dict[str, Any]]) -> dict[str, Any]:
    """The report entry of STL robot ``robot_id``: per sub-task ρ, r̄, repairs and the paper's
    values beside them (module docstring)."""
    subtasks = []
    for index, sub in enumerate(summary_entry["subtasks"]):
        value = paper_values.lookup(scenario_name, robot_id, sub["task"])
        rho = sub["robustness"]  # float (±inf: empty window) or None (not evaluated)
        r_bar = sub["r_least"]
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
            "robustness": sub["robustness"], "r_bar": r_bar, "r_final": sub["r_last"],
            "robustness_ge_r_bar": None if rho is None or r_bar is None else rho >= r_bar,
            "repairs": {f"stage{s}": (stages[s - 1] if len(stages) >= s else None)
                        for s in (1, 2, 3)},
            "repair_events": {f"stage{s}": n for s, n in zip((1, 2, 3), by_event, strict=True)},
            "paper": paper,
        })
    return {"robustness": summary_entry["robustness"], "subtasks": subtasks,
            "repair_events": summary_entry["repair_events"], "error": summary_entry["error"]}


def repair_events(events: Iterable[Event]) -> dict[int, list[dict[str, Any]]]:
    """``repair`` (and ``recovery``: stage "recovery") events per agent:
    ``[{t, stage, subtask, r}]``."""
    out: dict[int, list[dict[str, Any]]] = {}
    for e in events:
        head, _, tail = e.source.partition("/")
        if e.kind not in ("repair", "recovery") or head != "agent" or not tail.isdigit():
            continue
        data = e.data
        if e.kind == "recovery":
            out.setdefault(int(tail), []).append({
                "t": e.t, "stage": "recovery", "subtask": data.get("subtask"),
                "r": data.get("r") if isinstance(data.get("r"), int | float) else None})
            continue
        stage = data.get("stage")
        if not isinstance(stage, int):
            continue
        out.setdefault(int(tail), []).append({
            "t": e.t, "stage": stage, "subtask": data.get("subtask"),
            "r": data.get("r") if isinstance(data.get("r"), int | float) else None})
    return out
