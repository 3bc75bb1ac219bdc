"""Syntactic implication and contradiction (agent/ltl/implication.py), and the TGBA construction
that drops transitions into contradictory conjunctions (agent/ltl/tgba.py).

Soundness is checked against the exact lasso semantics (``tlfleet.agent.ltl.lasso``): on every pair
of small formulas over two atoms, exhaustively, and on random larger ones; a proven ``f ⇒ g`` must
hold on every lasso, a proven contradiction must have no lasso satisfying both. A table of
implications the translation relies on must be proven (an implementation that proves nothing
would be sound and useless).
"""

from __future__ import annotations

import itertools
import random

from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from ltl_helpers import automaton_accepts, formulas, lasso_words, random_lasso
from tlfleet.agent.ltl import tgba
from tlfleet.agent.ltl.buchi import _atoms_in_order, translate
from tlfleet.agent.ltl.formula import (
    FALSE,
    TRUE,
    And,
    Atom,
    Finally,
    Globally,
    Next,
    Not,
    Or,
    Release,
    Until,
    children,
)
from tlfleet.agent.ltl.graphs import reachable, strongly_connected_components
from tlfleet.agent.ltl.implication import Conflicts, Implication, negate
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.ltl.rewrite import normalize

INDEX = {"a": 0, "b": 1, "c": 2, "d": 3}


def _nnf_formulas(max_size: int) -> list:
    """Every NNF formula over a, b with at most ``max_size`` nodes (literals count one)."""
    by_size = {1: [Atom("a"), Not(Atom("a")), Atom("b"), Not(Atom("b")), TRUE, FALSE]}
    for size in range(2, max_size + 1):
        out = [op(x) for op in (Next, Finally, Globally) for x in by_size[size - 1]]
        for left in range(1, size - 1):
            for x in by_size[left]:
                for y in by_size[size - 1 - left]:
                    out += [And((x, y)), Or((x, y)), Until(x, y), Release(x, y)]
        by_size[size] = out
    return [f for size in sorted(by_size) for f in by_size[size]]


def _all_lassos():
    letters = [frozenset(s) for s in ((), ("a",), ("b",), ("a", "b"))]
    prefixes = [[]] + [[x] for x in letters]
    loops = [[x] for x in letters] + [[x, y] for x in letters for y in letters]
    return [(p, lp) for p in prefixes for lp in loops]


def test_every_proof_between_small_formulas_holds_on_every_short_lasso():
    fs = _nnf_formulas(3)
    lassos = _all_lassos()
    truth = {id(f): sum(holds(f, p, lp) << i for i, (p, lp) in enumerate(lassos)) for f in fs}
    full = (1 << len(lassos)) - 1
    imp = Implication(INDEX)
    proven = clashes = 0
    for f, g in itertools.product(fs, fs):
        if imp.implies(f, g):
            proven += 1
            assert not truth[id(f)] & ~truth[id(g)] & full, f"{f} ⇒ {g} proven, false on a lasso"
        if imp.contradict(f, g):
            clashes += 1
            assert not truth[id(f)] & truth[id(g)], f"{f} ∧ {g} proven empty, holds on a lasso"
    # Not a no-op: the rules prove a good share of what the lassos allow.
    assert proven > 4000 and clashes > 1500


def _related(f):
    """Formulas likely to be implied by, or to contradict, ``f``: its subformulas, their
    negations, and those under F, G, X."""
    subs, stack = [], [f]
    while stack:
        x = stack.pop()
        subs.append(x)
        stack.extend(children(x))
    base = subs + [negate(x) for x in subs]
    return st.sampled_from(base).flatmap(
        lambda x: st.sampled_from([x, Finally(x), Globally(x), Next(x), Or((x, Atom("c"))),
                                   Until(Atom("c"), x), Release(Atom("c"), x)]))


@settings(max_examples=examples(500), deadline=None)
@given(formulas(max_depth=4).map(normalize).flatmap(
    lambda f: st.tuples(st.just(f), _related(f), st.lists(lasso_words(), min_size=8,
                                                          max_size=8))))
def test_proofs_between_random_formulas_hold_on_random_lassos(case):
    f, g, words = case
    imp = Implication(INDEX)
    if imp.implies(f, g):
        for prefix, loop in words:
            assert not holds(f, prefix, loop) or holds(g, prefix, loop)
    if imp.contradict(f, g):
        for prefix, loop in words:
            assert not (holds(f, prefix, loop) and holds(g, prefix, loop))


def test_negate_is_the_complement():
    lassos = _all_lassos()
    for f in _nnf_formulas(3):
        n = negate(f)
        assert all(holds(n, p, lp) != holds(f, p, lp) for p, lp in lassos), f


IMPLIED = [
    ("G a", "a"), ("G a", "F a"), ("G a", "X a"), ("G a", "X G a"), ("a", "F a"),
    ("a & b", "a | c"), ("a U b", "F b"), ("b", "a U b"), ("a R b", "b"), ("G b", "a R b"),
    ("a & b", "a R b"), ("X(a & b)", "X a"), ("F X a", "F a"), ("G F a", "F a"),
    ("F G a", "F a"), ("a U b", "(a | c) U b"), ("(a & c) R b", "a R b"), ("X a", "F a"),
    ("G(a & b)", "G a"), ("F a | F b", "F(a | b)"),
]
CONTRADICTORY = [
    ("G !a", "F a"), ("a", "!a"), ("G X !a", "F X a"), ("G(!a | !b)", "F(a & b)"),
    ("F G a", "G F !a"), ("G a", "G F !a"), ("a U b", "!a R !b"), ("X a", "X !a"),
    ("G !a", "a"), ("F G a", "G !a"),
]
NOT_PROVEN = [
    ("F a", "G a"), ("a U b", "b"), ("F a", "a"), ("a R b", "G b"), ("X a", "a"),
]
COMPATIBLE = [("F a", "F !a"), ("G F a", "G F !a"), ("a U b", "!b"), ("X a", "!a")]


def _nnf(text: str):
    return normalize(parse(text))


def test_the_implications_the_translation_relies_on_are_proven():
    imp = Implication(INDEX)
    for f, g in IMPLIED:
        assert imp.implies(_nnf(f), _nnf(g)), f"{f} ⇒ {g}"
    for f, g in CONTRADICTORY:
        assert imp.contradict(_nnf(f), _nnf(g)), f"{f} ∧ {g}"
        assert imp.contradict(_nnf(g), _nnf(f)), f"{g} ∧ {f}"
    for f, g in NOT_PROVEN:
        assert not imp.implies(_nnf(f), _nnf(g)), f"{f} ⇒ {g} is false"
    for f, g in COMPATIBLE:
        assert not imp.contradict(_nnf(f), _nnf(g)), f"{f} ∧ {g} is satisfiable"


def test_conflicts_between_registered_states():
    states = [_nnf(x) for x in ("G !a", "F a", "F b", "b", "!b")]
    conflicts = Conflicts(states, INDEX)
    conflicts.register(0b00111)
    assert conflicts.masks == {0: 0b010, 1: 0b001, 2: 0}
    version = conflicts.version
    conflicts.register(0b11000)  # b, !b: a new contradiction, and both masks complete
    assert conflicts.version > version
    assert conflicts.masks[3] == 0b10000 and conflicts.masks[4] == 0b01000
    assert conflicts.empty(0b00011) and conflicts.empty(0b11000) and conflicts.empty(0b11111)
    assert not conflicts.empty(0b00101) and not conflicts.empty(0b01110)
    assert not conflicts.empty(0)
    assert conflicts.of(0b01001) == 0b10010


# The random-formula benchmark's #60 (bench/ltl_bench.py): its TGBA had 329 states, of which
# 274 could not reach an accepting cycle.
SLOW = ("F(G(!(((!(F(p5))) <-> (((X(p4)) xor ((true) U (p1))) W (X(p2)))) xor "
        "(F(X(p3))))))")


def _useful_states(t) -> set[int]:
    succ = [[d for d, _g, _m in out] for out in t.edges]
    _comp, components = strongly_connected_components(t.num_states, succ)
    full = (1 << t.num_marks) - 1
    good: set[int] = set()
    for members in components:
        inside = set(members)
        marks = 0
        cyclic = False
        for s in members:
            for d, _g, m in t.edges[s]:
                if d in inside:
                    marks |= m
                    cyclic = True
        if cyclic and marks == full:
            good |= inside
    pred: list[list[int]] = [[] for _ in succ]
    for s, out in enumerate(succ):
        for d in out:
            pred[d].append(s)
    return reachable(good, pred)


def _build(f, prune: bool):
    index = {a: i for i, a in enumerate(_atoms_in_order(f))}
    if prune:
        return tgba.build_tgba(normalize(f), index)
    original = tgba.Conflicts.register
    tgba.Conflicts.register = _register_without_contradictions
    try:
        return tgba.build_tgba(normalize(f), index)
    finally:
        tgba.Conflicts.register = original


def _register_without_contradictions(self, targets):
    """``Conflicts.register`` that finds no contradiction: the construction before pruning."""
    while targets:
        low = targets & -targets
        targets ^= low
        self.masks.setdefault(low.bit_length() - 1, 0)


def test_contradictory_conjunctions_are_not_entered():
    f = parse(SLOW)
    pruned, unpruned = _build(f, True)[0], _build(f, False)[0]
    assert len(_useful_states(pruned)) == pruned.num_states
    assert pruned.num_states < unpruned.num_states // 3
    rng = random.Random(60)
    atoms = [f"p{i}" for i in range(6)]
    b = translate(f)
    for _ in range(200):
        prefix, loop = random_lasso(rng, atoms)
        assert automaton_accepts(b, prefix, loop) == holds(f, prefix, loop)


def test_an_unsatisfiable_formula_gives_the_empty_automaton():
    for text in ("G a & F !a", "a & X b & X !b", "G F a & F G !a"):
        b = translate(text)
        assert b.num_states == 1 and not b.accepting and b.edges == ((),), text


@settings(max_examples=examples(300), deadline=None)
@given(formulas(max_depth=4), st.lists(lasso_words(), min_size=4, max_size=4))
def test_pruned_and_unpruned_tgba_accept_the_same_lassos(f, words):
    from tlfleet.agent.ltl.buchi import Buchi, _remove_useless
    from tlfleet.agent.ltl.degeneralize import degeneralize
    from tlfleet.agent.ltl.printer import to_string

    atoms = _atoms_in_order(f)
    for variant in (_build(f, True), _build(f, False)):
        n, initial, accepting, edges = _remove_useless(*degeneralize(variant[0]))
        if n == 0:
            b = Buchi(to_string(f), atoms, (0,), frozenset(), ((),))
        else:
            b = Buchi(to_string(f), atoms, tuple(initial), frozenset(accepting),
                      tuple(tuple(out) for out in edges))
        for prefix, loop in words:
            assert automaton_accepts(b, prefix, loop) == holds(f, prefix, loop)
