"""Postponed branching: merging the nondeterministic successors of a TGBA (ltl-planning.md §2).

Gastin–Oddoux automata branch as soon as a disjunction is met (``G(a -> F b | G c)`` chooses at
once between waiting for ``b`` and committing to ``G c``). Formula-based translators such as
Spot's keep such choices inside one state until the letters force them. The same effect on a
TGBA: the states of the new automaton are *sets* of old states; from a set ``D``, a letter
``σ`` and an acceptance-mark set ``M`` lead to the set of all old states reachable from a member
of ``D`` by an edge reading ``σ`` with exactly the marks ``M``.

Language preserved: every old run is a run of the new automaton with the same marks; and an
infinite run of the new automaton ``D0 –σ0,M0→ D1 –σ1,M1→ …`` contains an old run with the same
marks, because every member of ``D(i+1)`` is reached from some member of ``Di`` by ``σi, Mi``,
so the backward chains form an infinite, finitely branching tree (König's lemma).

The construction can grow (it is a subset construction restricted to equal marks), so it stops
at ``limit`` states and the caller keeps the plain automaton.
"""

from __future__ import annotations

from collections import deque

from tlfleet.agent.ltl.bdd import FALSE
from tlfleet.agent.ltl.tgba import Tgba


def postpone_branching(tgba: Tgba, limit: int) -> Tgba | None:
    """The merged automaton, or ``None`` when it would exceed ``limit`` states or nothing
    branches."""
    if len(tgba.initial) < 2 and not any(_branches(out) for out in tgba.edges):
        return None
    ids: dict[frozenset[int], int] = {}
    order: list[frozenset[int]] = []
    queue: deque[frozenset[int]] = deque()

    def intern(members: frozenset[int]) -> int:
        sid = ids.get(members)
        if sid is None:
            sid = len(order)
            ids[members] = sid
            order.append(members)
            queue.append(members)
        return sid

    initial = (intern(frozenset(tgba.initial)),)
    edges: list[tuple[tuple[int, object, int], ...]] = []
    while queue:
        members = queue.popleft()
        by_marks: dict[int, list[tuple[int, object]]] = {}
        for q in sorted(members):
            for dst, guard, marks in tgba.edges[q]:
                by_marks.setdefault(marks, []).append((dst, guard))
        out = []
        for marks, group in by_marks.items():
            parts: list[tuple[object, frozenset[int]]] = []
            for dst, guard in group:
                new_parts = []
                rest = guard
                for part_guard, dsts in parts:
                    both = part_guard & guard
                    only = part_guard - guard
                    if both is not FALSE:
                        new_parts.append((both, dsts | {dst}))
                        rest = rest - both
                    if only is not FALSE:
                        new_parts.append((only, dsts))
                if rest is not FALSE:
                    new_parts.append((rest, frozenset((dst,))))
                parts = new_parts
            merged: dict[frozenset[int], object] = {}
            for part_guard, dsts in parts:
                merged[dsts] = merged.get(dsts, FALSE) | part_guard
            for dsts, guard in merged.items():
                out.append((intern(dsts), guard, marks))
                if len(order) > limit:
                    return None
        edges.append(tuple(out))
    return Tgba(len(order), initial, tuple(edges), tgba.num_marks)


def _branches(out) -> bool:
    """Whether two edges with the same marks read a common letter (edges are grouped by
    destination and marks, so they lead to different states)."""
    seen: dict[int, object] = {}
    for _d, guard, marks in out:
        before = seen.get(marks, FALSE)
        if guard & before is not FALSE:
            return True
        seen[marks] = before | guard
    return False
