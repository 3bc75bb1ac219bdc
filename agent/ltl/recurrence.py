"""Conjunctions of many recurrences ``χ ∧ G F φ_1 ∧ … ∧ G F φ_n`` (φ_i propositional), built
as a round-robin counter instead of through the tableau (ltl-planning.md §2).

Why: the tableau gives ``G F φ_1 ∧ … ∧ G F φ_n`` one state with an edge for every subset of the
φ_i that a letter satisfies — 2^n edges, each carrying its marks — and degeneralisation then works
through all of them: ``G F p1 & … & G F p20`` took over 120 s and 1.9 GB. Each ``G F φ_i`` is
an invariant obligation that only marks the letters satisfying φ_i, whatever the state, so the
automaton of the whole is the automaton ``B`` of χ in product with a counter over the round
robin ``(F_B, φ_1, …, φ_n)``:

* states ``(q, i)`` with ``q`` a state of ``B`` and ``i ∈ 0..m`` the next item awaited
  (``m = n + 1``; ``n`` when every state of ``B`` accepts, and ``F_B`` is dropped);
* from ``(q, i)``, with ``b = 0`` when ``i = m`` (the round just completed) and ``b = i``
  otherwise, an edge ``q →g q'`` of ``B`` goes to ``(q', b + 1)`` on the letters that fulfil item
  ``b`` (``φ_j``: ``g ∧ φ_j``; ``F_B``: all of ``g`` if ``q ∈ F_B``) and to ``(q', b)`` on the
  others;
* ``(q, m)`` accepts.

A run visits the accepting level infinitely often iff it completes the round infinitely often,
i.e. iff it meets ``F_B`` and every φ_i infinitely often (each completion needs all of them in
order, and each of them infinitely often lets the counter always advance again). For ``χ = true``
it is the n + 1 states and 2(n + 1) edges of ``G F p1 & … & G F pn``: linear in n.
"""

from __future__ import annotations

from tlfleet.agent.ltl.bdd import FALSE, TRUE, var
from tlfleet.agent.ltl.formula import And, Atom, Const, Finally, Formula, Globally, Not, Or
from tlfleet.agent.ltl.guards import Guard

#: recurrence conjuncts from which the direct construction is used; below it the tableau is
#: fast (10 conjuncts: 60 ms) and its reductions keep the automata the paper's tasks always had
MIN_RECURRENCES = 8

Automaton = tuple[int, tuple[int, ...], frozenset[int], list[list[tuple[int, Guard]]]]


def split_recurrences(tree: Formula) -> tuple[Formula | None, list[Formula]]:
    """``(χ, [φ_1, …, φ_n])`` of a normalised ``χ ∧ G F φ_1 ∧ … ∧ G F φ_n`` (``χ`` None when
    nothing else is conjoined); ``(tree, [])`` when it is not such a conjunction."""
    args = tree.args if isinstance(tree, And) else (tree,)
    rest: list[Formula] = []
    recurrences: list[Formula] = []
    for arg in args:
        if (isinstance(arg, Globally) and isinstance(arg.arg, Finally)
                and is_propositional(arg.arg.arg)):
            recurrences.append(arg.arg.arg)
        else:
            rest.append(arg)
    if not recurrences:
        return tree, []
    if not rest:
        return None, recurrences
    return (rest[0] if len(rest) == 1 else And(tuple(rest))), recurrences


def is_propositional(f: Formula) -> bool:
    match f:
        case Const() | Atom():
            return True
        case Not(arg):
            return is_propositional(arg)
        case And(args) | Or(args):
            return all(is_propositional(a) for a in args)
    return False


def propositional_guard(f: Formula, index: dict[str, int]) -> Guard:
    """The guard (BDD over the atoms of ``index``) of a propositional formula."""
    match f:
        case Const(value):
            return TRUE if value else FALSE
        case Atom(name):
            return var(index[name])
        case Not(arg):
            return ~propositional_guard(arg, index)
        case And(args):
            out = TRUE
            for a in args:
                out = out & propositional_guard(a, index)
            return out
        case Or(args):
            out = FALSE
            for a in args:
                out = out | propositional_guard(a, index)
            return out
    raise TypeError(f"not propositional: {f!r}")


def round_robin(base: Automaton, guards: list[Guard]) -> Automaton:
    """The product of the state-based Büchi automaton ``base`` (of χ) with the counter over its
    acceptance and the ``guards`` φ_i (module docstring): ``(num_states, initial, accepting,
    edges)``, states numbered in breadth-first order."""
    n_base, initial, accepting, edges = base
    items: list[Guard | None] = ([] if len(accepting) == n_base else [None]) + list(guards)
    m = len(items)  # the accepting level
    ids: dict[tuple[int, int], int] = {}
    order: list[tuple[int, int]] = []

    def intern(q: int, level: int) -> int:
        key = (q, level)
        sid = ids.get(key)
        if sid is None:
            sid = ids[key] = len(order)
            order.append(key)
        return sid

    start = tuple(intern(q, 0) for q in initial)
    out: list[list[tuple[int, Guard]]] = []
    k = 0
    while k < len(order):
        q, level = order[k]
        b = 0 if level == m else level
        item = items[b] if b < m else None
        step: dict[int, Guard] = {}
        for dst, g in edges[q]:
            if b == m:  # nothing awaited (m = 0: χ alone, every state accepting)
                parts = [(dst, b, g)]
            elif item is None:  # F_B: a state-based mark, on the source
                parts = [(dst, b + 1 if q in accepting else b, g)]
            else:
                parts = [(dst, b + 1, g & item), (dst, b, g & ~item)]
            for d, lvl, guard in parts:
                if guard is FALSE:
                    continue
                sid = intern(d, lvl)
                step[sid] = step[sid] | guard if sid in step else guard
        out.append(list(step.items()))
        k += 1
    accept = frozenset(sid for (q, level), sid in ids.items() if level == m)
    return len(order), start, accept, out


TRIVIAL: Automaton = (1, (0,), frozenset({0}), [[(0, TRUE)]])
"""The automaton of ``true``: every word."""
