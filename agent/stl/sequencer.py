"""Conjunctions φ′ ∧ φ″ ∧ … of one robot run as a sequence of sub-tasks (stl-funnel.md §9).

[OUR CHOICE] sequential executor: sub-tasks are ordered by a and need b^(k) ≤ a^(k+1); two
consecutive G sub-tasks with the same window are merged into G_[a,b](ψ′ ∧ ψ″); any other overlap is
an error (outside the fragment). Sub-task k+1 is activated when sub-task k is done (§8), or, with
``phase_start_times``, at max(done time, phase_start_times[k]); a forced time must be ≥ b^(k)
(§13 item 6). The overall robustness of the conjunction is the min over sub-tasks (§9 item 6).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from tlfleet.agent.stl.errors import StlTaskError
from tlfleet.agent.stl.parser import parse_task
from tlfleet.agent.stl.supremum import Workspace
from tlfleet.agent.stl.syntax import And, Temporal, literals
from tlfleet.agent.stl.task import Task, build_task


def merge_and_check(owner: int, formulas: Sequence[Temporal]) -> list[Temporal]:
    """Order check and same-window G merge of a robot's sub-task formulas (§9 item 1)."""
    merged: list[Temporal] = []
    for k, phi in enumerate(formulas):
        if merged:
            prev = merged[-1]
            if phi.op == prev.op == "G" and (phi.a, phi.b) == (prev.a, prev.b):
                merged[-1] = Temporal("G", phi.a, phi.b,
                                      And(literals(prev.body) + literals(phi.body)))
                continue
            if prev.b > phi.a:
                raise StlTaskError(
                    f"robot {owner} sub-task {k + 1}: window [{phi.a:g}, {phi.b:g}] starts before "
                    f"the previous one ends (b = {prev.b:g}); sub-tasks run in sequence and need "
                    f"b(k) <= a(k+1) (stl-funnel.md §9)")
        merged.append(phi)
    return merged


def check_phase_start_times(owner: int, tasks: Sequence[Task],
                            phase_start_times: Sequence[float] | None) -> tuple[float, ...] | None:
    """Validate forced activation times: one per sub-task after the first, entry k ≥ b^(k)."""
    if phase_start_times is None:
        return None
    times = tuple(float(t) for t in phase_start_times)
    if len(times) != len(tasks) - 1:
        raise StlTaskError(f"robot {owner}: phase_start_times has {len(times)} entries, expected "
                           f"{len(tasks) - 1} (one per sub-task after the first)")
    for k, t in enumerate(times):
        if t < tasks[k].b:
            raise StlTaskError(f"robot {owner}: phase_start_times[{k}] = {t:g} precedes the end "
                               f"b = {tasks[k].b:g} of sub-task {k + 1}")
    return times


def build_sequence(owner: int, texts: Iterable[str | Temporal], *,
                   robot_ids: Iterable[int] | None = None, stl_ids: Iterable[int] | None = None,
                   rho_opt: Sequence[float | None] = (), eta: float = 10.0,
                   warn: bool = True, workspace: Workspace | None = None,
                   poses: tuple[tuple[int, tuple[float, float, float]], ...] = ()
                   ) -> tuple[Task, ...]:
    """Parse, merge and build every sub-task of robot ``owner`` (``rho_opt[k]``: override or None;
    without one, the supremum over ``workspace`` from the start ``poses``, ``build_task``).

    Overrides are matched to the sub-tasks after merging (a merged pair takes the first override).
    """
    ids = None if robot_ids is None else tuple(robot_ids)
    formulas = [t if isinstance(t, Temporal) else parse_task(t, ids) for t in texts]
    merged = merge_and_check(owner, formulas)
    tasks = []
    for k, phi in enumerate(merged):
        override = rho_opt[k] if k < len(rho_opt) else None
        tasks.append(build_task(phi, owner, k, robot_ids=ids, stl_ids=stl_ids, rho_opt=override,
                                eta=eta, warn=warn, workspace=workspace, poses=poses))
    return tuple(tasks)


def overall_robustness(values: Iterable[float]) -> float:
    """ρ of φ′ ∧ φ″ ∧ … with the standard semantics: min over the sub-tasks (§9 item 6)."""
    return min(values, default=math.inf)
