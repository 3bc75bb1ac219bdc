"""Direct simulation (agent/ltl/simulation.py) against a reference computed letter by letter.

The reference is the textbook greatest fixpoint: start from "q accepting if p is" and remove
(p, q) while some letter takes p to p' with no move of q on that letter to a q' with p' ≼ q'.
It shares nothing with the implementation's symbolic covers and its extra necessary conditions
(letters read, letters into accepting states), so a condition that is not necessary would make
the two differ.
"""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis_budget import examples
from ltl_helpers import formulas, guard_holds
from tlfleet.agent.ltl import simulation, tgba, tgba_simulation
from tlfleet.agent.ltl.buchi import _atoms_in_order, _cheap_reduce, _remove_useless
from tlfleet.agent.ltl.degeneralize import degeneralize
from tlfleet.agent.ltl.rewrite import normalize
from tlfleet.agent.ltl.truth_table import guard_algebra


def _reference_simulation(n, accepting, edges, atoms):
    moves = [[[d for d, g in edges[p] if guard_holds(g, v)] for v in range(1 << atoms)]
             for p in range(n)]
    sim = {(p, q) for p in range(n) for q in range(n) if q in accepting or p not in accepting}
    changed = True
    while changed:
        changed = False
        for p, q in list(sim):
            for v in range(1 << atoms):
                if any(all((p2, q2) not in sim for q2 in moves[q][v]) for p2 in moves[p][v]):
                    sim.discard((p, q))
                    changed = True
                    break
    return [{q for q in range(n) if (p, q) in sim} for p in range(n)]


@settings(max_examples=examples(250), deadline=None)
@given(formulas())
def test_direct_simulation_is_the_greatest_simulation(f):
    atoms = _atoms_in_order(f)
    index = {a: i for i, a in enumerate(atoms)}
    n, _initial, accepting, edges = _cheap_reduce(_remove_useless(*degeneralize(
        tgba.build_tgba(normalize(f), index)[0])))
    if n > 24:
        return
    expected = _reference_simulation(n, accepting, edges, len(atoms))
    assert simulation.direct_simulation(n, accepting, edges) == expected
    algebra = guard_algebra(len(atoms))
    tables = [[(d, algebra.from_bdd(g)) for d, g in out] for out in edges]
    assert simulation.direct_simulation(n, accepting, tables, tables=True) == expected


def _reference_tgba_simulation(tgba, atoms):
    """p ≼ q: every move p –σ,M→ p' is answered by some q –σ,M'→ q' with M ⊆ M', p' ≼ q'."""
    n = tgba.num_states
    moves = [[[(d, m) for d, g, m in tgba.edges[p] if guard_holds(g, v)]
              for v in range(1 << atoms)] for p in range(n)]
    sim = {(p, q) for p in range(n) for q in range(n)}
    changed = True
    while changed:
        changed = False
        for p, q in list(sim):
            if any(all(m & ~m2 or (p2, q2) not in sim for q2, m2 in moves[q][v])
                   for v in range(1 << atoms) for p2, m in moves[p][v]):
                sim.discard((p, q))
                changed = True
    return [{q for q in range(n) if (p, q) in sim} for p in range(n)]


@settings(max_examples=examples(250), deadline=None)
@given(formulas())
def test_tgba_simulation_is_the_greatest_simulation_and_tables_change_nothing(f):
    atoms = _atoms_in_order(f)
    index = {a: i for i, a in enumerate(atoms)}
    algebra = guard_algebra(len(atoms))
    for t in tgba.build_tgba(normalize(f), index):
        if t.num_states > 24:
            continue
        edges = [tgba_simulation._grouped(out) for out in t.edges]
        expected = _reference_tgba_simulation(t, len(atoms))
        assert tgba_simulation.tgba_simulation(t.num_states, edges, t.num_marks) == expected
        tables = [{k: algebra.from_bdd(g) for k, g in out.items()} for out in edges]
        assert tgba_simulation.tgba_simulation(t.num_states, tables, t.num_marks,
                                               tables=True) == expected
        assert tgba_simulation.reduce_tgba(t, len(atoms)) == tgba_simulation.reduce_tgba(t)
