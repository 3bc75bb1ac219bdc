"""Degeneralisation: TGBA with k acceptance sets → state-based Büchi automaton (ltl-planning.md §2).

The classic counter construction (states ``(q, level)``, accept when every set has been seen in
order) made SCC-aware, as Spot's ``degeneralize`` is (Babiak et al., ATVA 2013):

* acceptance marks only matter on edges inside an SCC, so levels live per SCC and reset to 0
  when the run enters another SCC;
* an SCC whose internal edges miss some mark altogether can never be accepting: one level,
  non-accepting; a trivial SCC (no internal edge) likewise;
* marks that every internal edge of the SCC carries are dropped; if none is left, every cycle of
  the SCC is accepting and its states get a single, accepting level;
* otherwise the remaining marks ``r_1 … r_m`` are awaited in order, jumping over every mark the
  edge carries, and level ``m`` is the accepting copy (after it the count restarts).
"""

from __future__ import annotations

from collections import deque

from tlfleet.agent.ltl.bdd import disjoin
from tlfleet.agent.ltl.graphs import strongly_connected_components
from tlfleet.agent.ltl.guards import Guard
from tlfleet.agent.ltl.tgba import Tgba


def degeneralize(
    tgba: Tgba, reverse: bool = False,
) -> tuple[int, tuple[int, ...], frozenset[int], list[list[tuple[int, Guard]]]]:
    """Returns ``(num_states, initial, accepting, edges)`` of the state-based automaton.

    The marks are awaited in increasing order, or decreasing with ``reverse``: the language is
    the same, the size may differ (as with Spot's ``degen-order``), so the translator tries both.
    """
    comp, relevant = _relevant_marks(tgba, reverse)
    ids: dict[tuple[int, int], int] = {}
    accepting: set[int] = set()
    edges: list[dict[int, list[Guard]]] = []
    queue: deque[tuple[int, int]] = deque()

    def intern(q: int, level: int) -> int:
        key = (q, level)
        sid = ids.get(key)
        if sid is None:
            sid = len(ids)
            ids[key] = sid
            edges.append({})
            rel = relevant[comp[q]]
            if rel is not None and level == len(rel):
                accepting.add(sid)
            queue.append(key)
        return sid

    initial = tuple(intern(q, 0) for q in tgba.initial)
    while queue:
        q, level = queue.popleft()
        sid = ids[(q, level)]
        rel = relevant[comp[q]]
        for dst, guard, marks in tgba.edges[q]:
            if comp[dst] != comp[q] or rel is None:
                target = 0
            else:
                target = 0 if level == len(rel) else level
                while target < len(rel) and marks >> rel[target] & 1:
                    target += 1
            did = intern(dst, target)
            edges[sid].setdefault(did, []).append(guard)
    out = [[(d, gs[0] if len(gs) == 1 else disjoin(gs)) for d, gs in e.items()]
           for e in edges]  # balanced ORs
    return len(ids), initial, frozenset(accepting), out


def _relevant_marks(tgba: Tgba, reverse: bool) -> tuple[list[int], list[tuple[int, ...] | None]]:
    """SCC of each state, and per SCC the marks awaited in order (``None``: cannot accept)."""
    n = tgba.num_states
    succ = [[dst for dst, _g, _m in tgba.edges[s]] for s in range(n)]
    comp, components = strongly_connected_components(n, succ)
    all_marks = (1 << tgba.num_marks) - 1
    relevant: list[tuple[int, ...] | None] = []
    for c, members in enumerate(components):
        internal = [
            marks for s in members for dst, _g, marks in tgba.edges[s] if comp[dst] == c
        ]
        if not internal:
            relevant.append(None)
            continue
        union = 0
        common = all_marks
        for marks in internal:
            union |= marks
            common &= marks
        if union != all_marks:
            relevant.append(None)
            continue
        order = range(tgba.num_marks - 1, -1, -1) if reverse else range(tgba.num_marks)
        relevant.append(tuple(j for j in order if not common >> j & 1))
    return comp, relevant


def mark_order_matters(tgba: Tgba) -> bool:
    """Whether some SCC awaits two marks or more, so that :func:`degeneralize` with ``reverse``
    can give another automaton."""
    return any(r is not None and len(r) > 1 for r in _relevant_marks(tgba, False)[1])
