"""Direct-simulation reduction of a transition-based generalised Büchi automaton (ltl-planning.md
§2, "Small"), before degeneralisation, as Spot's ``simulation()`` runs on TGBA.

Direct simulation with acceptance on edges (Etessami, Wilke & Schuller 2005; Babiak et al.,
ATVA 2013): ``p ≼ q`` when every edge ``p –σ,M→ p'`` is matched by an edge ``q –σ,M'→ q'`` with
``M ⊆ M'`` (at least the same acceptance marks) and ``p' ≼ q'``. Then ``L(p) ⊆ L(q)``, and:

* states that simulate each other are merged (each keeps the representative's edges);
* a letter on an edge ``s –M→ p`` is dropped when an edge ``s –M'→ q`` reads it too, with
  ``M ⊆ M'`` and ``p ≺ q`` strictly ("little brothers"): any run through ``p`` is matched,
  mark for mark, by one through ``q``.

Both preserve the language; the property tests compare automata by exact lasso evaluation.
Computed as a greatest fixpoint with guards as BDDs, a letter set at a time.
"""

from __future__ import annotations

from agent.ltl.bdd import FALSE, Bdd, disjoin
from agent.ltl.simulation import refine_simulation
from agent.ltl.tgba import Tgba

MAX_TGBA_SIMULATION_STATES = 32
"""Larger TGBA skip the (quadratic) simulation."""


def _grouped(out) -> dict[tuple[int, int], Bdd]:
    grouped: dict[tuple[int, int], Bdd] = {}
    for dst, guard, marks in out:
        key = (dst, marks)
        grouped[key] = grouped.get(key, FALSE) | guard
    return grouped


def tgba_simulation(n: int, edges: list[dict[tuple[int, int], Bdd]]) -> list[set[int]]:
    """``sim[p]`` = the states ``q`` with ``p ≼ q``; ``edges[p]`` maps ``(dst, marks)`` to a
    guard. Greatest fixpoint (``agent.ltl.simulation.refine_simulation``) from "``q`` reads
    every letter ``p`` reads"."""
    reads = [disjoin(out.values()) for out in edges]
    sim = [{q for q in range(n) if q == p or reads[p].implies(reads[q])} for p in range(n)]
    return refine_simulation(n, sim, [[(d, m, g) for (d, m), g in out.items()]
                                      for out in edges])


def reduce_tgba(tgba: Tgba) -> Tgba:
    """Quotient by simulation equivalence and little-brother pruning (see module docstring)."""
    n = tgba.num_states
    if (n < 2 or n > MAX_TGBA_SIMULATION_STATES or tgba.deterministic
            or _is_deterministic(tgba)):
        return tgba
    edges = [_grouped(out) for out in tgba.edges]
    sim = tgba_simulation(n, edges)
    rep = list(range(n))
    for p in range(n):
        for q in sim[p]:
            if q < rep[p] and p in sim[q]:
                rep[p] = q
    reps = sorted(set(rep))
    if len(reps) == n and not _has_little_brothers(edges, sim):
        return tgba
    new_id = {r: i for i, r in enumerate(reps)}
    new_edges = []
    for r in reps:
        grouped: dict[tuple[int, int], Bdd] = {}
        for (dst, marks), guard in edges[r].items():
            key = (rep[dst], marks)
            grouped[key] = grouped.get(key, FALSE) | guard
        pruned = []
        for (d, m), guard in grouped.items():
            for (d2, m2), g2 in grouped.items():
                if (d2, m2) != (d, m) and not m & ~m2 and d2 in sim[d] and (
                        d not in sim[d2] or d2 == d):
                    # d2 == d: same destination with more marks dominates.
                    guard = guard - g2
                    if guard is FALSE:
                        break
            if guard is not FALSE:
                pruned.append((new_id[d], guard, m))
        new_edges.append(tuple(pruned))
    initial = tuple(dict.fromkeys(new_id[rep[q]] for q in tgba.initial))
    return Tgba(len(reps), initial, tuple(new_edges), tgba.num_marks)


def _is_deterministic(tgba: Tgba) -> bool:
    """One initial state and pairwise disjoint guards: nothing for simulation to prune, and
    simulation-equivalent states are already bisimilar (merged by ``build_tgba``)."""
    if len(tgba.initial) > 1:
        return False
    for out in tgba.edges:
        seen = FALSE
        for _d, guard, _m in out:
            if guard & seen is not FALSE:
                return False
            seen = seen | guard
    return True


def _has_little_brothers(edges, sim) -> bool:
    for out in edges:
        for d, m in out:
            for d2, m2 in out:
                if (d2, m2) != (d, m) and not m & ~m2 and d2 in sim[d] and (
                        d not in sim[d2] or d2 == d):
                    return True
    return False
