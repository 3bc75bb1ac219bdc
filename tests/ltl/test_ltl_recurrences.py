"""Many recurrences, ``χ ∧ G F φ_1 ∧ … ∧ G F φ_n``, built as a round-robin counter
(``tlfleet.agent.ltl.recurrence``), and inputs that used to cost quadratic or unbounded work.

Correctness is checked independently: the automaton's acceptance of random lasso words against
the exact LTL semantics on those words (``tlfleet.agent.ltl.lasso``), with words drawn so that
the recurrences hold on about half of them."""

from __future__ import annotations

import random

import pytest
from ltl_helpers import automaton_accepts
from tlfleet.agent.ltl.buchi import translate
from tlfleet.agent.ltl.formula import And, Atom, Or
from tlfleet.agent.ltl.hoa_reader import read_hoa
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.ltl.recurrence import MIN_RECURRENCES
from tlfleet.bus.errors import LtlError

N = MIN_RECURRENCES + 1
RECURRENCES = [f"G F p{i}" for i in range(N - 2)] + ["G F (p0 | !q)", "G F (q & !p1)"]
ATOMS = (*(f"p{i}" for i in range(N - 2)), "q", "a", "b", "c")


def biased_lasso(rng: random.Random) -> tuple[list[frozenset[str]], list[frozenset[str]]]:
    """A prefix of 0–3 letters and a loop of 1–6; each p_i and q in a letter with probability
    0.85, so a loop often holds every recurrence (and often misses one); a, b, c with 0.5."""
    def letter() -> frozenset[str]:
        return frozenset(a for a in ATOMS if rng.random() < (0.5 if a in "abc" else 0.85))

    return ([letter() for _ in range(rng.randrange(4))],
            [letter() for _ in range(1 + rng.randrange(6))])


@pytest.mark.parametrize("rest", [None, "G (a -> F b)", "F G c", "a U b", "X a", "G !c",
                                  "F a & G (b -> X c)", "G F a | F G b"])
def test_the_round_robin_accepts_exactly_the_words_of_the_formula(rest):
    formula = " & ".join(([f"({rest})"] if rest else []) + RECURRENCES)
    buchi = translate(formula)
    rng = random.Random(f"{rest}")
    outcomes = []
    for _ in range(400):
        prefix, loop = biased_lasso(rng)
        expected = holds(formula, prefix, loop)
        assert automaton_accepts(buchi, prefix, loop) == expected, (formula, prefix, loop)
        outcomes.append(expected)
    assert any(outcomes) and not all(outcomes)  # both answers were exercised


@pytest.mark.parametrize("n", [MIN_RECURRENCES, 16, 64])
def test_g_f_p1_to_pn_has_n_plus_1_states_and_linear_edges(n):
    buchi = translate(" & ".join(f"G F p{i}" for i in range(1, n + 1)))
    assert buchi.num_states == n + 1 and buchi.num_edges == 2 * (n + 1)
    assert len(buchi.accepting) == 1 and len(buchi.initial) == 1


def test_below_the_threshold_the_tableau_is_kept():
    """The paper's tasks have a few recurrences: their automata come from the tableau, as
    before (G F a & G F b: 3 states, the edge set of the degeneralised TGBA)."""
    buchi = translate("G F a & G F b")
    assert buchi.num_states == 3 and buchi.num_edges > 2 * 3


def test_a_long_conjunction_parses_into_one_flat_node():
    """``a & a & … & a`` (and ``|``): gathered in one list, not copied at every operator."""
    n = 20_000
    tree = parse(" & ".join(["a"] * n))
    assert isinstance(tree, And) and len(tree.args) == n and set(tree.args) == {Atom("a")}
    mixed = parse("a & (b & c) & d | e | (f | g)")
    a, b, c, d, e, f, g = (Atom(x) for x in "abcdefg")
    assert mixed == Or((And((a, b, c, d)), e, f, g))
    assert translate(" & ".join(["a"] * n)).num_states == 2


def test_deep_hoa_labels_are_one_line_errors():
    head = 'HOA: v1\nStates: 1\nStart: 0\nAP: 1 "a"\nAcceptance: 1 Inf(0)\n--BODY--\nState: 0 {0}\n'
    with pytest.raises(LtlError, match="nested more than 256 parentheses"):
        read_hoa(head + "[" + "(" * 10_000 + "0" + ")" * 10_000 + "] 0\n--END--\n")
    flipped = read_hoa(head + "[" + "!" * 100_001 + "0] 0\n--END--\n")  # odd: !a
    assert flipped.edges[0][0][1].holds(0) and not flipped.edges[0][0][1].holds(1)
