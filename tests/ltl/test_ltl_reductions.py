"""Language-preserving reductions of issue 16 (ltl-planning.md §2, "Small"): Spot-style rewrite
rules, TGBA direct simulation, degeneralisation in both mark orders, and the minimal weak DBA of
obligation formulas. Each is checked against the exact lasso semantics of the formula."""

from __future__ import annotations

import random

from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from ltl_helpers import automaton_accepts, formulas, lasso_words
from tlfleet.agent.ltl import bdd
from tlfleet.agent.ltl.buchi import (
    Buchi,
    _atoms_in_order,
    _remove_useless,
    translate,
    translation_candidates,
)
from tlfleet.agent.ltl.degeneralize import degeneralize
from tlfleet.agent.ltl.fair_simulation import (
    _Moves,
    fair_simulation_positions,
    remove_fair_little_brothers,
)
from tlfleet.agent.ltl.formula import And, Atom, Finally, Globally, Next, Not, Or, Release, Until
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.ltl.printer import to_string
from tlfleet.agent.ltl.rewrite import normalize
from tlfleet.agent.ltl.tgba import build_tgba
from tlfleet.agent.ltl.tgba_simulation import reduce_tgba
from tlfleet.agent.ltl.wdba import _equivalent, minimize_obligation

WORDS = st.lists(lasso_words(), min_size=1, max_size=4)


def _tuple(b: Buchi):
    return b.num_states, b.initial, b.accepting, [list(out) for out in b.edges]


def _buchi(f, atoms, aut) -> Buchi:
    n, initial, accepting, edges = aut
    if n == 0:
        return Buchi(to_string(f), atoms, (), frozenset(), ())
    return Buchi(to_string(f), atoms, tuple(initial), frozenset(accepting),
                 tuple(tuple(out) for out in edges))


def _check(f, buchi, words):
    for prefix, loop in words:
        assert automaton_accepts(buchi, prefix, loop) == holds(f, prefix, loop), (
            f"{f} on {prefix} ({loop})^ω")


small = formulas(max_depth=3)
shapes = st.one_of(
    st.builds(lambda a, b: Until(a, Or((b, Globally(a)))), small, small),  # a U (b | G a)
    st.builds(lambda a, b: Release(a, And((b, Finally(a)))), small, small),  # a R (b & F a)
    st.builds(lambda a, b: Or((Finally(a), Finally(b))), small, small),
    st.builds(lambda a, b: Or((Next(a), Next(b))), small, small),
    st.builds(lambda a, b: And((Next(a), Next(b))), small, small),
    st.builds(lambda a, b: Or((Until(a, b), Globally(a))), small, small),  # a W b
    st.builds(lambda a, b: And((Release(a, b), Finally(a))), small, small),  # a M b
    # G a | F(!a & e), e eventual
    st.builds(lambda a, b, c: Or((Globally(a), Finally(And((Not(a), Finally(b), c))))),
              st.sampled_from([Atom("a"), Atom("b")]), small, small),
    st.builds(lambda a, b: Or((Globally(Not(a)), Finally(And((a, Finally(b)))))),
              st.sampled_from([Atom("a"), Atom("b")]), small),
    # universal u: u U (u & x) = u & F x, x U (x & e) = x & e; duals with an eventual e
    st.builds(lambda a, b: Until(Globally(a), And((Globally(a), b))), small, small),
    st.builds(lambda a, b: Until(Next(Globally(a)), And((b, Next(Globally(a))))), small, small),
    st.builds(lambda a, b: Until(a, And((a, Finally(b)))), small, small),
    st.builds(lambda a, b: Release(Finally(a), Or((Finally(a), b))), small, small),
    st.builds(lambda a, b: Release(a, Or((Globally(b), a))), small, small),
)


@settings(max_examples=examples(600), deadline=None)
@given(shapes, WORDS)
def test_new_rewrite_rules_preserve_semantics(f, words):
    g = normalize(f)
    for prefix, loop in words:
        assert holds(g, prefix, loop) == holds(f, prefix, loop), f"{f} rewritten to {g}"


def test_rewrite_rules_fire():
    assert to_string(normalize(parse("a U (b | G a)"))) == to_string(normalize(parse("a W b")))
    assert to_string(normalize(parse("F a | F b"))) == "F(a | b)"
    assert to_string(normalize(parse("X a & X b"))) == "X(a & b)"
    assert to_string(normalize(parse("G a | a U b"))) == to_string(normalize(parse("a W b")))
    assert to_string(normalize(parse("G !a | F(a & F b)"))) == to_string(
        normalize(parse("!a W (a & F b)")))
    assert to_string(normalize(parse("G a U (b U c & G a)"))) == "G a & F c"
    assert to_string(normalize(parse("F a R (b R c | F a)"))) == "F a | G c"
    assert to_string(normalize(parse("a U (a & F b)"))) == "a & F b"
    assert to_string(normalize(parse("a R (a | G b)"))) == "a | G b"


@settings(max_examples=examples(600), deadline=None)
@given(formulas(), WORDS)
def test_tgba_simulation_and_both_degeneralisation_orders_preserve_the_language(f, words):
    atoms = _atoms_in_order(f)
    index = {a: i for i, a in enumerate(atoms)}
    for tgba in build_tgba(normalize(f), index):
        reduced = reduce_tgba(tgba)
        assert reduced.num_states <= tgba.num_states
        for reverse in (False, True):
            aut = _remove_useless(*degeneralize(reduced, reverse=reverse))
            _check(f, _buchi(f, atoms, aut), words)


def _negation(f):
    return lambda: _tuple(translate(Not(f)))


@settings(max_examples=examples(400), deadline=None)
@given(formulas(), WORDS)
def test_minimal_weak_dba_when_accepted_has_the_language_of_the_formula(f, words):
    b = translation_candidates(f)[-1]  # a variant with the cheap reductions only
    atoms = b.atoms
    wdba = minimize_obligation(_tuple(b), _negation(f))
    if wdba is not None:
        assert wdba[0] < b.num_states
        _check(f, _buchi(f, atoms, wdba), words)


def test_weak_dba_shrinks_an_obligation_and_refuses_a_recurrence():
    f = parse("G(p0 -> (F p1 -> (!p1 U (p2 | (!p1 & p3 & X(!p1 U p4))))))")  # Spot: 3 states
    assert translate(f).num_states == 3
    g = parse("G F a & G F b")  # not an obligation: the check must refuse the weak DBA
    b = translate(g)
    assert minimize_obligation(_tuple(b), _negation(g)) is None
    assert b.num_states == 3


def test_equivalence_check_separates_languages():
    both, together = translate("F a & F b"), translate("F(a & b)")
    assert both.atoms == together.atoms
    assert _equivalent(_tuple(both), _tuple(both), lambda: _tuple(translate("!(F a & F b)")))
    # L(F(a & b)) ⊊ L(F a & F b): the second product (F a & F b with ¬F(a & b)) is not empty.
    assert not _equivalent(_tuple(together), _tuple(both),
                           lambda: _tuple(translate("!F(a & b)")))


@settings(max_examples=examples(500), deadline=None)
@given(formulas(), WORDS)
def test_fair_little_brothers_removal_preserves_the_language(f, words):
    for b in translation_candidates(f):
        lighter = remove_fair_little_brothers(_tuple(b))
        if lighter is not None:
            _check(f, _buchi(f, b.atoms, _remove_useless(*lighter)), words)


def _edges(*rows):
    """Guards over one atom ``a`` (variable 0): 'a', '!a' or 'true'."""
    guard = {"a": bdd.var(0), "!a": ~bdd.var(0), "true": bdd.TRUE}
    return [[(d, guard[g]) for d, g in row] for row in rows]


def test_fair_simulation_sees_through_an_accepting_copy():
    # G F a with the accepting copy 1 of state 0: 1 ≼f 0 (same successors, acceptance one
    # step later) although 1 ≼ 0 fails for direct simulation; a^ω-only 2 is not above F a.
    edges = _edges([(0, "!a"), (1, "a")], [(0, "!a"), (1, "a")], [(2, "a")])
    aut = (3, (0,), frozenset({1, 2}), edges)
    win = fair_simulation_positions(3, 3, aut[2], aut[2], _Moves(edges, edges))
    assert (1, 0) in win and (0, 1) in win
    assert (0, 2) not in win and (2, 0) in win  # L(G a) ⊆ L(G F a), not conversely


def test_dac_response_chain_loses_the_state_of_its_early_choice():
    # Spot: 7 states; direct simulation alone leaves 9 (the G-branch entered before the pending
    # X((!p2 & !p4) U p5) is fulfilled); fair simulation removes it.
    f = parse("G(p0 -> ((p1 -> (!p2 U (!p2 & p3 & !p4 & X((!p2 & !p4) U p5)))) U "
              "(p2 | G(p1 -> (p3 & !p4 & X(!p4 U p5))))))")
    b = translate(f)
    assert b.num_states == 8
    rng = random.Random(7)
    for _ in range(400):
        prefix = [frozenset(f"p{i}" for i in range(6) if rng.random() < 0.4)
                  for _ in range(rng.randrange(4))]
        loop = [frozenset(f"p{i}" for i in range(6) if rng.random() < 0.4)
                for _ in range(1 + rng.randrange(4))]
        assert automaton_accepts(b, prefix, loop) == holds(f, prefix, loop)


PRUNED_BY_FAIR_SIMULATION = [  # seeded random formulas on which the removal fires
    "F X(p0 <-> true) M ((p3 -> G p3) & p2)",
    "!(G p3 M (F p0 -> p3) W (!p3 | p2) W p0)",
    "G(F(!(F X p2 M p3) <-> X p0) & p3)",
    "!X p1 & F(p0 W (p1 | G p0))",
    "X F p3 U G p0",
    "(!p0 & X p1) U F(p0 R p0 | X X p0)",
    "G p3 U !p3 -> G p3",
    "p3 R p1 & F(F p3 | X p0)",
    "!(X p2 R p3 & (G p3 M p1 U p3) R X p2)",
    "p2 <-> F G(G p1 & !p0)",
]


def test_fair_little_brothers_removal_on_seeded_lassos():
    rng = random.Random(2024)
    fired = 0
    for text in PRUNED_BY_FAIR_SIMULATION:
        f = parse(text)
        for b in translation_candidates(f):
            lighter = remove_fair_little_brothers(_tuple(b))
            if lighter is None:
                continue
            fired += 1
            pruned = _buchi(f, b.atoms, _remove_useless(*lighter))
            assert pruned.num_states < b.num_states
            for _ in range(300):
                prefix = [frozenset(f"p{i}" for i in range(4) if rng.random() < 0.5)
                          for _ in range(rng.randrange(4))]
                loop = [frozenset(f"p{i}" for i in range(4) if rng.random() < 0.5)
                        for _ in range(1 + rng.randrange(4))]
                assert automaton_accepts(pruned, prefix, loop) == holds(f, prefix, loop), text
    assert fired >= len(PRUNED_BY_FAIR_SIMULATION)
