"""The determinism that ``build_tgba`` records (``Tgba.deterministic``) and the reductions trust
instead of checking again (``agent.ltl.buchi._reduce``, ``agent.ltl.wdba.powerset``): a flag that
is ``True`` on a nondeterministic automaton would make the weak-DBA construction read it as its
own subset construction, a language error."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
from ltl_helpers import automaton_accepts, formulas, lasso_words

from agent.ltl.bdd import FALSE
from agent.ltl.buchi import _atoms_in_order, translate
from agent.ltl.lasso import holds
from agent.ltl.parser import parse
from agent.ltl.rewrite import normalize
from agent.ltl.tgba import build_tgba


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


@settings(max_examples=400, deadline=None)
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
