"""Emptiness check with an accepting-lasso witness (ltl-planning.md §2, item 2).

The language of a Büchi automaton is non-empty iff some accepting state lies on a cycle and is
reachable from an initial state. The witness is a lasso word ``prefix · loop^ω`` (letters are
sets of atoms) read along such a path: BFS to the accepting state, BFS back to it.

:func:`accepts_lasso` is the converse membership test: does the automaton accept a given lasso
word (the run report checks executed runs with it)?
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

from tlfleet.agent.ltl.buchi import Buchi
from tlfleet.agent.ltl.graphs import bfs_path, nontrivial, reachable, strongly_connected_components

Lasso = tuple[tuple[frozenset[str], ...], tuple[frozenset[str], ...]]


def accepting_lassos(buchi: Buchi, limit: int | None = None) -> list[Lasso]:
    """One accepting lasso word per reachable accepting state on a cycle (at most ``limit``)."""
    n = buchi.num_states
    succ = [[dst for dst, _g in out] for out in buchi.edges]
    comp, components = strongly_connected_components(n, succ)
    cyclic = nontrivial(comp, components, succ)
    live = reachable(buchi.initial, succ)
    alphabet = buchi.alphabet
    guard_of = [dict() for _ in range(n)]
    for q, out in enumerate(buchi.edges):
        for dst, guard in out:
            guard_of[q][dst] = guard

    def letters(path: list[int]) -> tuple[frozenset[str], ...]:
        return tuple(
            alphabet.smallest_letter(guard_of[a][b], buchi.atoms)
            for a, b in itertools.pairwise(path)
        )

    result: list[Lasso] = []
    for acc in sorted(buchi.accepting):
        if acc not in live or not cyclic[comp[acc]]:
            continue
        stem = None
        for init in buchi.initial:
            stem = bfs_path(init, {acc}, succ)
            if stem is not None:
                break
        cycle = bfs_path(acc, {acc}, succ, nonempty=True)
        if stem is None or cycle is None:
            continue
        result.append((letters(stem), letters(cycle)))
        if limit is not None and len(result) >= limit:
            break
    return result


def find_accepting_lasso(buchi: Buchi) -> Lasso | None:
    """An accepting lasso word of ``buchi``, or ``None`` when its language is empty."""
    found = accepting_lassos(buchi, limit=1)
    return found[0] if found else None


def is_empty(buchi: Buchi) -> bool:
    return find_accepting_lasso(buchi) is None


def accepts_lasso(buchi: Buchi, prefix: Sequence[frozenset[str]],
                  loop: Sequence[frozenset[str]]) -> bool:
    """Does ``buchi`` accept the lasso word ``prefix · loop^ω`` (letters: sets of atoms)?

    Product of the automaton with the ``n`` positions of ``prefix + loop`` (position ``i`` has the
    successor ``i + 1``, the last one ``len(prefix)``): node ``(q, i)`` → ``(q', succ(i))`` for
    ``q' ∈ Δ(q, letter_i)``. Accepted iff an accepting ``q`` sits on a cycle of the product
    reachable from ``(q₀, 0)``; cycles can only run through loop positions.
    """
    if not loop:
        raise ValueError("the loop of a lasso word must not be empty")
    letters = [*prefix, *loop]
    n = len(letters)
    succ_pos = [*range(1, n), len(prefix)]
    states = buchi.num_states

    def node(q: int, i: int) -> int:
        return q * n + i

    succ: list[list[int]] = [[] for _ in range(states * n)]
    for q in range(states):
        for i, letter in enumerate(letters):
            succ[node(q, i)] = [node(dst, succ_pos[i]) for dst in buchi.successors(q, letter)]
    comp, components = strongly_connected_components(len(succ), succ)
    cyclic = nontrivial(comp, components, succ)
    live = reachable([node(q, 0) for q in buchi.initial], succ)
    return any(v // n in buchi.accepting and cyclic[comp[v]] for v in live)
