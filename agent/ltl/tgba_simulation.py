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
Computed as a greatest fixpoint a letter set at a time, with guards as BDDs or, over few atoms,
as truth tables (the same relation).
"""

from __future__ import annotations

from tlfleet.agent.ltl.bdd import FALSE, Bdd, disjoin
from tlfleet.agent.ltl.simulation import refine_simulation, union_of_tables
from tlfleet.agent.ltl.tgba import Tgba
from tlfleet.agent.ltl.truth_table import BddAlgebra, TableAlgebra, guard_algebra

MAX_TGBA_SIMULATION_STATES = 32
"""Larger TGBA skip the (quadratic) simulation."""


def _grouped(out) -> dict[tuple[int, int], Bdd]:
    grouped: dict[tuple[int, int], Bdd] = {}
    for dst, guard, marks in out:
        key = (dst, marks)
        grouped[key] = grouped.get(key, FALSE) | guard
    return grouped


def tgba_simulation(n: int, edges: list[dict[tuple[int, int], Bdd]], num_marks: int = 0,
                    tables: bool = False) -> list[set[int]]:
    """``sim[p]`` = the states ``q`` with ``p ≼ q``; ``edges[p]`` maps ``(dst, marks)`` to a
    guard (BDDs, or truth tables when ``tables``). Greatest fixpoint
    (``tlfleet.agent.ltl.simulation.refine_simulation``) from "``q`` reads every letter ``p`` reads,
    and for each mark ``j``, every letter on which ``p`` takes an edge marked ``j``" (both
    necessary: an edge of ``p`` is answered on the same letter with at least its marks)."""
    if tables:
        # The letters read, then those read with mark j for each j, side by side in one int
        # (each table below 2**width): the condition is one inclusion test.
        width = max((g.bit_length() for out in edges for g in out.values()), default=0)
        key = []
        for out in edges:
            k = union_of_tables(out.values())
            for j in range(num_marks):
                k |= union_of_tables(g for (_d, m), g in out.items() if m >> j & 1) << (
                    (j + 1) * width)
            key.append(k)
        sim = [{q for q in range(n) if not key[p] & ~key[q]} for p in range(n)]
    else:
        reads = [disjoin(out.values()) for out in edges]
        marked = [[disjoin(g for (_d, m), g in out.items() if m >> j & 1)
                   for j in range(num_marks)] for out in edges]
        sim = [{q for q in range(n)
                if q == p or (reads[p].implies(reads[q])
                              and all(a.implies(b)
                                      for a, b in zip(marked[p], marked[q], strict=True)))}
               for p in range(n)]
    return refine_simulation(n, sim, [[(d, m, g) for (d, m), g in out.items()]
                                      for out in edges], tables)


def reduce_tgba(tgba: Tgba, atoms: int | None = None) -> Tgba:
    """Quotient by simulation equivalence and little-brother pruning (see module docstring).

    With ``atoms`` (the number of atoms the guards range over) the simulation runs on truth
    tables when there are few (``tlfleet.agent.ltl.truth_table``); the result is the same."""
    n = tgba.num_states
    if (n < 2 or n > MAX_TGBA_SIMULATION_STATES or tgba.deterministic
            or _is_deterministic(tgba)):
        return tgba
    algebra = guard_algebra(atoms) if atoms is not None else BddAlgebra()
    tables = isinstance(algebra, TableAlgebra)
    edges = [_grouped(out) for out in tgba.edges]
    if tables:
        edges = [{key: algebra.from_bdd(g) for key, g in out.items()} for out in edges]
    sim = tgba_simulation(n, edges, tgba.num_marks, tables)
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
            old = grouped.get(key)
            grouped[key] = guard if old is None else old | guard
        by_dst: dict[int, list[tuple[int, Bdd]]] = {}
        for (d, m), guard in grouped.items():
            by_dst.setdefault(d, []).append((m, guard))
        pruned = []
        for (d, m), guard in grouped.items():
            for d2 in sim[d]:  # (few simulators: cheaper than every pair of edges)
                if d2 != d and d in sim[d2]:
                    continue
                for m2, g2 in by_dst.get(d2, ()):
                    if (d2 != d or m2 != m) and not m & ~m2:
                        # d2 == d: same destination with more marks dominates.
                        guard = guard & ~g2
                        if not guard:
                            break
                if not guard:
                    break
            if guard:
                pruned.append((new_id[d], algebra.to_bdd(guard), m))
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
