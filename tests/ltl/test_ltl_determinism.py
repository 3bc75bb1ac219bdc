"""The determinism that ``build_tgba`` records (``Tgba.deterministic``) and the reductions trust
instead of checking again (``tlfleet.agent.ltl.buchi._reduce``,
``tlfleet.agent.ltl.wdba.powerset``): a flag that is ``True`` on a nondeterministic automaton would
make the weak-DBA construction read it as its own subset construction, a language error."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from ltl_helpers import automaton_accepts, formulas, lasso_words
from tlfleet.agent.ltl.bdd import FALSE
from tlfleet.agent.ltl.buchi import _atoms_in_order, translate
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.ltl.rewrite import normalize
from tlfleet.agent.ltl.tgba import build_tgba


def _really_deterministic(tgba) -> bool:
    if len(tgba.initial) > 1:
        return False
    for out in tgba.edges:
        guards = [g for _d, g, _m in out]
        for i, g in enumerate(guards):
            if any(g & h is not FALSE for h in guards[:i]):
                return False
    return True


def _tgbas(text_or_tree):
    f = parse(text_or_tree) if isinstance(text_or_tree, str) else text_or_tree
    index = {a: i for i, a in enumerate(_atoms_in_order(f))}
    return build_tgba(normalize(f), index)


@settings(max_examples=examples(400), deadline=None)
@given(formulas(), st.lists(lasso_words(), min_size=3, max_size=3))
def test_a_tgba_flagged_deterministic_is_deterministic(f, words):
    for tgba in _tgbas(f):
        if tgba.deterministic:
            assert _really_deterministic(tgba)
    b = translate(f)
    for prefix, loop in words:
        assert automaton_accepts(b, prefix, loop) == holds(f, prefix, loop)


def test_the_flag_is_set_where_the_scenarios_need_it():
    for text in ("F a1 & F a2 & F a3 & F a4 & F a5", "G F a11 & G F a12", "G(a -> X b)"):
        assert all(t.deterministic for t in _tgbas(text)), text
    for text in ("F G a", "a U b | G c", "F a | F b & G c"):
        assert not any(t.deterministic and not _really_deterministic(t)
                       for t in _tgbas(text)), text
    assert not _tgbas("F G a")[0].deterministic


@settings(max_examples=examples(300), deadline=None)
@given(formulas())
def test_weak_dba_minimisation_trusting_the_flag_is_the_same(f):
    """minimize_obligation(deterministic=True) decides without the subset construction when
    nothing would change; it must answer exactly as the full construction does."""
    from tlfleet.agent.ltl.buchi import _cheap_reduce, _remove_useless
    from tlfleet.agent.ltl.degeneralize import degeneralize
    from tlfleet.agent.ltl.formula import Not
    from tlfleet.agent.ltl.wdba import minimize_obligation

    index = {a: i for i, a in enumerate(_atoms_in_order(f))}
    for tgba in build_tgba(normalize(f), index):
        if not tgba.deterministic:
            continue
        aut = _cheap_reduce(_remove_useless(*degeneralize(tgba)))

        def negation():
            return _remove_useless(*degeneralize(build_tgba(normalize(Not(f)), index)[0]))

        trusted = minimize_obligation(aut, negation, deterministic=True)
        checked = minimize_obligation(aut, negation, deterministic=False)
        assert (trusted is None) == (checked is None)
        if trusted is not None:
            assert trusted[:3] == checked[:3]
            assert [list(out) for out in trusted[3]] == [list(out) for out in checked[3]]


def test_weak_dba_shortcut_keeps_a_deterministic_automaton_that_moore_shrinks():
    """A deterministic automaton of "a, then anything" whose acceptance the colouring
    changes: 0 reads a into the accepting sink 1 and !a into 2, accepting but transient, then
    the rejecting sink 3. The colouring rejects 2, so the shortcut must not answer "nothing
    to gain": Moore's quotient merges 2 and 3."""
    from tlfleet.agent.ltl import bdd
    from tlfleet.agent.ltl.wdba import minimize_obligation

    a = bdd.var(0)
    aut = (4, (0,), frozenset({1, 2}),
           [[(1, a), (2, ~a)], [(1, bdd.TRUE)], [(3, bdd.TRUE)], [(3, bdd.TRUE)]])

    def negation():  # "!a, then anything"
        return 2, (0,), frozenset({1}), [[(1, ~a)], [(1, bdd.TRUE)]]

    for trusted in (True, False):
        smaller = minimize_obligation(aut, negation, deterministic=trusted)
        assert smaller is not None and smaller[0] == 3 and smaller[2] == frozenset({1})
