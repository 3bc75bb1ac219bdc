"""The guards' BDD package against truth tables (the representation it replaced), and the
symbolic translation paths it enables."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from tlfleet.agent.ltl import bdd
from tlfleet.agent.ltl.guards import Alphabet

N = 5
FULL = (1 << (1 << N)) - 1


def _table_of_var(i: int) -> int:
    return sum(1 << v for v in range(1 << N) if v >> i & 1)


expressions = st.recursive(
    st.one_of(st.integers(0, N - 1).map(lambda i: ("var", i)), st.sampled_from([("t",), ("f",)])),
    lambda inner: st.one_of(
        st.tuples(st.just("not"), inner),
        st.tuples(st.sampled_from(["and", "or", "sub"]), inner, inner),
    ),
    max_leaves=12,
)


def _build(e):
    """(BDD, truth table) of an expression."""
    match e:
        case ("var", i):
            return bdd.var(i), _table_of_var(i)
        case ("t",):
            return bdd.TRUE, FULL
        case ("f",):
            return bdd.FALSE, 0
        case ("not", x):
            g, t = _build(x)
            return ~g, FULL & ~t
        case (op, x, y):
            gx, tx = _build(x)
            gy, ty = _build(y)
            if op == "and":
                return gx & gy, tx & ty
            if op == "or":
                return gx | gy, tx | ty
            return gx - gy, tx & ~ty
    raise AssertionError(e)


@settings(max_examples=examples(400), deadline=None)
@given(expressions, expressions)
def test_bdd_operations_agree_with_truth_tables(e1, e2):
    g1, t1 = _build(e1)
    g2, t2 = _build(e2)
    for v in range(1 << N):
        assert g1.holds(v) == bool(t1 >> v & 1)
    # Canonical: equal functions are the same node; implication is table inclusion.
    assert (g1 is g2) == (t1 == t2)
    assert g1.implies(g2) == (t1 & ~t2 == 0)


@settings(max_examples=examples(300), deadline=None)
@given(expressions)
def test_isop_cover_and_smallest_letter(e):
    g, t = _build(e)
    alphabet = Alphabet(N)
    names = tuple(f"x{i}" for i in range(N))
    cover = 0
    for pos, neg in alphabet.cubes(g):
        assert not pos & neg
        cover |= sum(1 << v for v in range(1 << N) if v & pos == pos and not v & neg)
    assert cover == t
    if t:
        letter = alphabet.smallest_letter(g, names)
        v = sum(1 << i for i, name in enumerate(names) if name in letter)
        assert t >> v & 1
        assert len(letter) == min(w.bit_count() for w in range(1 << N) if t >> w & 1)


@settings(max_examples=examples(300), deadline=None)
@given(expressions)
def test_pick_valuation_satisfies_the_guard(e):
    g, table = _build(e)
    if g is bdd.FALSE:
        return
    v = bdd.pick_valuation(g)
    assert g.holds(v)
    assert table >> v & 1
