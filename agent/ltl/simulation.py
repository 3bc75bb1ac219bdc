"""Reductions of a state-based Büchi automaton by direct simulation (ltl-planning.md §2, "Small").

All work on the tuple ``(n, initial, accepting, edges)`` with ``edges[q]`` a list of
``(dst, guard)`` (BDD guards, ``tlfleet.agent.ltl.guards``) and preserve the language:

* :func:`single_initial` — one initial state: a fresh state with the union of the initial
  states' edges (the old ones disappear when nothing else enters them);
* :func:`saturate_acceptance` — in an SCC whose non-accepting states lie on no cycle of their
  own, every infinite path visits accepting states infinitely often, so all its states may be
  accepting (more states then simulate one another);
* :func:`direct_simulation` — the direct-simulation preorder (Dill, Hu & Wong-Toi 1991;
  Etessami, Wilke & Schuller 2005): ``p ≼ q`` when ``q`` accepting if ``p`` is, and every edge
  ``p –σ→ p'`` is matched by some ``q –σ→ q'`` with ``p' ≼ q'``; computed as a greatest
  fixpoint with guards as BDDs (a letter set at a time, not a letter at a time);
* :func:`reduce_by_simulation` — quotient by simulation equivalence, and removal of the
  "little brothers": a letter on ``s → p`` is dropped when ``s → q`` reads it too and
  ``p ≺ q`` strictly (Bustan & Grumberg 2003; Clemente & Mayr 2013, direct simulation).
"""

from __future__ import annotations

from tlfleet.agent.ltl.bdd import FALSE, disjoin
from tlfleet.agent.ltl.graphs import nontrivial, strongly_connected_components
from tlfleet.agent.ltl.truth_table import BddAlgebra, TableAlgebra, guard_algebra

MAX_SIMULATION_STATES = 128
"""Larger automata skip the (quadratic) simulation; robot missions stay far below."""


def is_deterministic(initial, edges) -> bool:
    """One initial state and no letter on two edges of a state. Such automata are already
    reduced by the bisimulation quotient: simulation has no little brothers to prune."""
    if len(initial) > 1:
        return False
    for out in edges:
        seen = FALSE
        for _d, guard in out:
            if guard & seen is not FALSE:
                return False
            seen = seen | guard
    return True


def single_initial(n, initial, accepting, edges):
    """One initial state (a fresh one when there are several)."""
    if len(initial) <= 1:
        return n, initial, accepting, edges
    merged: dict[int, object] = {}
    for q in initial:
        for dst, guard in edges[q]:
            merged[dst] = merged.get(dst, FALSE) | guard
    new = n
    edges = [*edges, list(merged.items())]
    # The fresh state is on no cycle: its acceptance never matters; accepting if any was.
    acc = set(accepting)
    if any(q in accepting for q in initial):
        acc.add(new)
    return n + 1, (new,), frozenset(acc), edges


def saturate_acceptance(n, initial, accepting, edges):
    """Mark every state of an SCC accepting when all its cycles already are accepting."""
    succ = [[dst for dst, _g in out] for out in edges]
    comp, components = strongly_connected_components(n, succ)
    cyclic = nontrivial(comp, components, succ)
    acc = set(accepting)
    for c, members in enumerate(components):
        if not cyclic[c] or all(s in acc for s in members) or not any(s in acc for s in members):
            continue
        inside = set(members) - acc
        sub = {s: [d for d in succ[s] if d in inside] for s in inside}
        ids = {s: i for i, s in enumerate(inside)}
        local = [[ids[d] for d in sub[s]] for s in inside]
        lcomp, lcomponents = strongly_connected_components(len(local), local)
        if not any(nontrivial(lcomp, lcomponents, local)):
            acc.update(members)
    return n, initial, frozenset(acc), edges


def direct_simulation(n, accepting, edges, tables: bool = False) -> list[set[int]]:
    """``sim[p]`` = the states ``q`` with ``p ≼ q`` (``q`` direct-simulates ``p``).

    Greatest fixpoint (:func:`refine_simulation`) from "``q`` accepting if ``p`` is, ``q``
    reads every letter ``p`` reads, and moves to an accepting state on every letter on which
    ``p`` does" (each necessary: a move of ``p`` into an accepting state is answered by a
    move into a state simulating it, accepting too). Guards are BDDs, or truth tables (ints,
    ``tlfleet.agent.ltl.truth_table``) when ``tables``."""
    if tables:
        reads = [union_of_tables(g for _d, g in out) for out in edges]
        into = [union_of_tables(g for d, g in out if d in accepting) for out in edges]
        sim = [{q for q in range(n)
                if (q in accepting or p not in accepting) and not reads[p] & ~reads[q]
                and not into[p] & ~into[q]}
               for p in range(n)]
    else:
        reads = [disjoin(g for _d, g in out) for out in edges]
        into = [disjoin(g for d, g in out if d in accepting) for out in edges]
        sim = [
            {q for q in range(n)
             if (q in accepting or p not in accepting)
             and (q == p or (reads[p].implies(reads[q]) and into[p].implies(into[q])))}
            for p in range(n)
        ]
    return refine_simulation(n, sim, [[(d, 0, g) for d, g in out] for out in edges], tables)


def union_of_tables(tables) -> int:
    union = 0
    for t in tables:
        union |= t
    return union


def refine_simulation(n, sim: list[set[int]], edges, tables: bool = False) -> list[set[int]]:
    """Refine the candidate sets ``sim`` (``p ∈ sim[p]``) to the greatest simulation inside them,
    for edges ``edges[p] = [(dst, marks, guard), …]`` (``marks`` 0 for state-based acceptance):
    drop ``q`` from ``sim[p]`` while some edge ``p –g,M→ d`` has letters that no edge
    ``q –g',M'→ d'`` with ``d' ∈ sim[d]`` and ``M ⊆ M'`` reads. The cover "letters on which ``q``
    answers ``(d, M)``" is cached until ``sim[d]`` shrinks. Shared by the state-based reduction
    here and the TGBA one (``tlfleet.agent.ltl.tgba_simulation``). Guards are BDDs, or truth tables
    (ints) when ``tables``: then inclusion is ``not a & ~b``, with no call."""
    version = [0] * n
    cache: dict[tuple[int, int, int], tuple[int, object]] = {}
    pred: list[set[int]] = [set() for _ in range(n)]
    for p in range(n):
        for d, _m, _g in edges[p]:
            pred[d].add(p)

    def cover(q: int, d: int, marks: int):
        key = (q, d, marks)
        hit = cache.get(key)
        if hit is not None and hit[0] == version[d]:
            return hit[1]
        members = sim[d]
        union = union_of_tables if tables else disjoin
        result = union(g for d2, m2, g in edges[q] if d2 in members and not marks & ~m2)
        cache[key] = (version[d], result)
        return result

    def answers(q: int, dst: int, marks: int, guard) -> bool:
        """Whether ``q`` answers ``p –guard,marks→ dst``: one matching edge reading all of
        ``guard`` (an inclusion test, no BDD built) or, failing that, the cover. (BDD guards;
        the same inlined below for truth tables.)"""
        members = sim[dst]
        for d2, m2, g in edges[q]:
            if d2 in members and not marks & ~m2 and guard.implies(g):
                return True
        return guard.implies(cover(q, dst, marks))

    pending = set(range(n))  # states whose simulators must be re-checked
    while pending:
        p = pending.pop()
        shrunk = False
        for q in list(sim[p]):
            if q == p:
                continue
            if tables:  # answers() inlined: one matching edge, else the cover
                out_q = edges[q]
                for dst, marks, guard in edges[p]:
                    members = sim[dst]
                    for d2, m2, g in out_q:
                        if d2 in members and not marks & ~m2 and not guard & ~g:
                            break
                    else:
                        if guard & ~cover(q, dst, marks):
                            sim[p].discard(q)
                            shrunk = True
                            break
                continue
            for dst, marks, guard in edges[p]:
                if not answers(q, dst, marks, guard):
                    sim[p].discard(q)
                    shrunk = True
                    break
        if shrunk:
            version[p] += 1
            pending |= pred[p]  # their covers into p's simulators changed
    return sim


def reduce_by_simulation(n, initial, accepting, edges, atoms: int | None = None):
    """Quotient by simulation equivalence, then drop edges to strictly simulated brothers.

    With ``atoms`` (the number of atoms the guards range over) the work is done on truth
    tables when there are few (``tlfleet.agent.ltl.truth_table``); the result is the same."""
    if n > MAX_SIMULATION_STATES or n == 0 or is_deterministic(initial, edges):
        return n, initial, accepting, edges
    algebra = guard_algebra(atoms) if atoms is not None else BddAlgebra()
    tables = isinstance(algebra, TableAlgebra)
    if tables:
        edges = [[(d, algebra.from_bdd(g)) for d, g in out] for out in edges]
    sim = direct_simulation(n, accepting, edges, tables)
    # Equivalence classes: representative = smallest equivalent state.
    rep = list(range(n))
    for p in range(n):
        for q in sim[p]:
            if q < rep[p] and p in sim[q]:
                rep[p] = q
    reps = sorted(set(rep))
    new_id = {r: i for i, r in enumerate(reps)}
    new_edges = []
    for r in reps:
        grouped: dict[int, object] = {}
        for dst, guard in edges[r]:
            d = rep[dst]
            grouped[d] = grouped.get(d, algebra.false) | guard
        # Little brothers: letters to d are dropped when a strictly larger brother reads them.
        pruned = []
        for d, guard in grouped.items():
            for d2 in sim[d]:  # (few simulators: cheaper than every pair of edges)
                g2 = grouped.get(d2)
                if g2 is not None and d2 != d and d not in sim[d2]:
                    guard = guard & ~g2
                    if not guard:
                        break
            if guard:
                pruned.append((new_id[d], algebra.to_bdd(guard)))
        new_edges.append(pruned)
    return (
        len(reps),
        tuple(dict.fromkeys(new_id[rep[q]] for q in initial)),
        frozenset(new_id[rep[q]] for q in accepting),
        new_edges,
    )

