"""Exact LTL evaluation on lasso words u·v^ω, against hand-computed truth values."""

from __future__ import annotations

import pytest
from tlfleet.agent.ltl.lasso import evaluate, holds
from tlfleet.agent.ltl.parser import parse

E = frozenset()
A = frozenset({"a"})
B = frozenset({"b"})
AB = frozenset({"a", "b"})

CASES = [
    # formula, prefix, loop, holds
    ("a", [A], [E], True),
    ("a", [E], [A], False),
    ("X a", [E], [A], True),
    ("X X a", [E], [A, E], False),
    ("X X a", [E, E], [A], True),
    ("F a", [E, E], [E, A], True),
    ("F a", [A], [E], True),
    ("F a", [], [E, B], False),
    ("G a", [A], [A, A], True),
    ("G a", [A], [A, E], False),
    ("G F a", [E, E, E], [E, A], True),
    ("G F a", [A, A], [E], False),
    ("F G a", [E, B], [A], True),
    ("F G a", [A], [A, E], False),
    ("a U b", [A, A], [B], True),
    ("a U b", [A, E], [B], False),
    ("a U b", [], [A], False),  # strong until: b never comes
    ("a W b", [], [A], True),  # weak until: a forever is enough
    ("a W b", [A, E], [B], False),
    ("a R b", [], [B], True),  # b forever
    ("a R b", [B], [AB, E], True),  # released by a & b
    ("a R b", [B, A], [E], False),  # b fails before a releases it
    ("a M b", [], [B], False),  # strong release needs a
    ("a M b", [B], [AB], True),
    ("(F a) U b", [], [E, B], False),  # F a fails at 0 (no a ever)
    ("(F a) U b", [E], [B, A], True),
    ("G (a -> X b)", [], [A, B], True),
    ("G (a -> X b)", [], [A, A, B], False),
    ("G F a & G F b", [], [A, E, B], True),
    ("G F a & G F b", [], [A, E], False),
    ("a xor b", [AB], [E], False),
    ("a <-> b", [AB], [E], True),
    ("F (a & F (b & F a))", [A, B, E], [E], False),
    ("F (a & F (b & F a))", [A, B], [A, E], True),
    ("G (a U b)", [], [A, B], True),
    ("G (a U b)", [], [A, A, E, B], False),
    ("true", [], [E], True),
    ("false", [], [AB], False),
]


@pytest.mark.parametrize(("text", "prefix", "loop", "expected"), CASES)
def test_lasso_evaluation(text, prefix, loop, expected):
    assert holds(parse(text), prefix, loop) is expected
    assert holds(text, prefix, loop) is expected


def test_every_position_is_evaluated():
    # F a on ∅ a (∅)^ω: true at 0 and 1, false on the loop.
    assert evaluate(parse("F a"), [E, A], [E]) == (True, True, False)
    # a U b on the loop (a b)^ω starting at the loop
    assert evaluate(parse("a U b"), [], [A, B]) == (True, True)


def test_empty_loop_is_rejected():
    with pytest.raises(ValueError, match="loop"):
        holds("a", [A], [])
