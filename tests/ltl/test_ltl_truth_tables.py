"""Truth-table guards (agent/ltl/truth_table.py) and the constructions that use them.

The tables must be the BDDs' sets of letters exactly (checked letter by letter), the TGBA built
on tables must be the one built on BDDs (edge for edge), the simulation on tables the one on
BDDs, and the translated automata must accept exactly the lassos that satisfy the formula
(exact evaluation, ``tlfleet.agent.ltl.lasso``) — here on ``<->``/``xor``-heavy random formulas like
the benchmark's slow tail.
"""

from __future__ import annotations

import random

import pytest
from hypothesis import given, settings
from hypothesis_budget import examples
from ltl_helpers import automaton_accepts, formulas, guard_holds, random_lasso
from tlfleet.agent.ltl import bdd, simulation, tgba
from tlfleet.agent.ltl.buchi import _atoms_in_order, _cheap_reduce, _remove_useless, translate
from tlfleet.agent.ltl.degeneralize import degeneralize
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.ltl.rewrite import normalize
from tlfleet.agent.ltl.truth_table import MAX_TABLE_ATOMS, BddAlgebra, TableAlgebra, guard_algebra


def _random_bdd(rng: random.Random, n: int, depth: int) -> bdd.Bdd:
    if depth == 0 or rng.random() < 0.2:
        i = rng.randrange(n)
        return bdd.var(i) if rng.random() < 0.5 else ~bdd.var(i)
    a, b = _random_bdd(rng, n, depth - 1), _random_bdd(rng, n, depth - 1)
    return [a & b, a | b, a - b, ~a][rng.randrange(4)]


@pytest.mark.parametrize("n", [1, 2, 3, 6, MAX_TABLE_ATOMS])
def test_tables_are_the_bdds_letter_sets(n):
    algebra = TableAlgebra(n)
    rng = random.Random(n)
    letters = range(1 << n)
    for _ in range(60):
        g, h = _random_bdd(rng, n, 4), _random_bdd(rng, n, 4)
        tg, th = algebra.from_bdd(g), algebra.from_bdd(h)
        for table, guard in ((tg, g), (tg & th, g & h), (tg | th, g | h), (tg & ~th, g - h)):
            assert algebra.to_bdd(table) is guard
            holding = [v for v in letters if guard_holds(guard, v)]
            assert [v for v in letters if algebra.to_bdd(table).holds(v)] == holding
        assert (not tg & ~th) == g.implies(h)
    for _ in range(60):
        pos, neg = rng.getrandbits(n), rng.getrandbits(n)
        assert algebra.to_bdd(algebra.cube(pos, neg)) is bdd.cube(pos, neg)
    assert algebra.to_bdd(algebra.true) is bdd.TRUE and algebra.to_bdd(algebra.false) is bdd.FALSE


def test_algebra_choice_and_bad_input():
    assert isinstance(guard_algebra(6), TableAlgebra)
    assert guard_algebra(6) is guard_algebra(6)
    assert isinstance(guard_algebra(MAX_TABLE_ATOMS + 1), BddAlgebra)
    with pytest.raises(ValueError, match="truth tables over 11 atoms"):
        TableAlgebra(MAX_TABLE_ATOMS + 1)
    with pytest.raises(ValueError, match="must not test atom 1"):
        bdd.node(1, bdd.var(0), bdd.TRUE)
    assert bdd.node(0, bdd.FALSE, bdd.var(1)) is bdd.var(0) & bdd.var(1)


@settings(max_examples=examples(300), deadline=None)
@given(formulas())
def test_tgba_on_tables_is_the_tgba_on_bdds(f):
    index = {a: i for i, a in enumerate(_atoms_in_order(f))}
    g = normalize(f)
    on_tables = tgba.build_tgba(g, index)
    original = tgba.guard_algebra
    tgba.guard_algebra = lambda n: BddAlgebra()
    try:
        on_bdds = tgba.build_tgba(g, index)
    finally:
        tgba.guard_algebra = original
    assert on_tables == on_bdds


@settings(max_examples=examples(200), deadline=None)
@given(formulas())
def test_simulation_on_tables_is_the_simulation_on_bdds(f):
    atoms = _atoms_in_order(f)
    index = {a: i for i, a in enumerate(atoms)}
    aut = _cheap_reduce(_remove_useless(*degeneralize(tgba.build_tgba(normalize(f), index)[0])))
    on_bdds = simulation.reduce_by_simulation(*aut)
    on_tables = simulation.reduce_by_simulation(*aut, atoms=len(atoms))
    assert on_tables[:3] == on_bdds[:3]
    assert [list(out) for out in on_tables[3]] == [list(out) for out in on_bdds[3]]


def _random_formula(rng: random.Random, size: int, atoms: int) -> str:
    """The benchmark's random formulas (bench/ltl_bench.py), with more ``<->`` and ``xor``."""
    if size <= 1:
        return f"p{rng.randrange(atoms)}" if rng.random() < 0.95 else "true"
    if size == 2 or rng.random() < 0.35:
        return f"{rng.choice(['!', 'X', 'F', 'G'])}({_random_formula(rng, size - 1, atoms)})"
    op = rng.choice(["&", "|", "->", "<->", "<->", "xor", "xor", "U", "R", "W", "M"])
    left = rng.randrange(1, size - 1)
    return (f"({_random_formula(rng, left, atoms)}) {op} "
            f"({_random_formula(rng, size - 1 - left, atoms)})")


def test_random_equivalence_heavy_formulas_against_lasso_semantics():
    """300 formulas × 60 lassos, 0 mismatches (exact evaluation on the lasso)."""
    rng = random.Random(16)
    atoms = [f"p{i}" for i in range(4)]
    mismatches = []
    for _ in range(300):
        text = _random_formula(rng, rng.randrange(6, 14), 4)
        f = parse(text)
        b = translate(f)
        for _ in range(60):
            prefix, loop = random_lasso(rng, atoms)
            if automaton_accepts(b, prefix, loop) != holds(f, prefix, loop):
                mismatches.append((text, prefix, loop))
    assert mismatches == []


@pytest.mark.parametrize("n", [MAX_TABLE_ATOMS + 1, 16])
def test_beyond_the_table_limit_the_bdds_are_used(n):
    text = "F(" + " & ".join(f"p{i}" for i in range(n)) + ") & G(p0 -> X(p1 U p2))"
    f = parse(text)
    b = translate(f)
    assert len(b.atoms) == n > MAX_TABLE_ATOMS
    everything = frozenset(f"p{i}" for i in range(n))
    words = [([], [everything]), ([], [frozenset({"p0"})]), ([frozenset()], [everything]),
             ([everything, frozenset({"p1"})], [frozenset({"p2"}), everything])]
    for prefix, loop in words:
        assert automaton_accepts(b, prefix, loop) == holds(f, prefix, loop)


def test_translation_leaves_the_garbage_collector_as_it_found_it():
    import gc

    assert gc.isenabled()
    translate("G(a <-> F b)")
    assert gc.isenabled()
    gc.disable()
    try:
        translate("G(a xor F b)")
        assert not gc.isenabled()
    finally:
        gc.enable()
