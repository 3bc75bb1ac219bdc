"""LTL → Büchi translation (ltl-planning.md §2): language = exact lasso semantics, witnesses,
golden automata, HOA/text/dot output."""

from __future__ import annotations

import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from ltl_helpers import automaton_accepts, formulas, guard_holds, lasso_words
from tlfleet.agent.ltl.buchi import buchi_step, to_dot, to_text, translate, translation_candidates
from tlfleet.agent.ltl.emptiness import (
    accepting_lassos,
    accepts_lasso,
    find_accepting_lasso,
    is_empty,
)
from tlfleet.agent.ltl.hoa import to_hoa
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.ltl.rewrite import normalize

E = frozenset()


@settings(max_examples=examples(2000), deadline=None)
@given(formulas(), st.lists(lasso_words(), min_size=1, max_size=4))
def test_automaton_accepts_exactly_the_words_satisfying_the_formula(f, words):
    buchi = translate(f)
    for prefix, loop in words:
        assert automaton_accepts(buchi, prefix, loop) == holds(f, prefix, loop), (
            f"{f} on {prefix} ({loop})^ω"
        )


@settings(max_examples=examples(500), deadline=None)
@given(formulas(), st.lists(lasso_words(), min_size=1, max_size=3))
def test_every_marking_candidate_is_correct(f, words):
    """translate() keeps the smaller of two TGBA markings; both must have the right language."""
    for buchi in translation_candidates(f):
        for prefix, loop in words:
            assert automaton_accepts(buchi, prefix, loop) == holds(f, prefix, loop)


@settings(max_examples=examples(500), deadline=None)
@given(formulas(), st.lists(lasso_words(), min_size=1, max_size=3))
def test_negation_gets_the_complementary_language(f, words):
    negated = translate(parse(f"!({f})"))
    for prefix, loop in words:
        assert automaton_accepts(negated, prefix, loop) != holds(f, prefix, loop)


@settings(max_examples=examples(500), deadline=None)
@given(formulas(), st.lists(lasso_words(), min_size=1, max_size=3))
def test_rewriting_preserves_semantics(f, words):
    g = normalize(f)
    for prefix, loop in words:
        assert holds(g, prefix, loop) == holds(f, prefix, loop), f"{f} rewritten to {g}"


@settings(max_examples=examples(1000), deadline=None)
@given(formulas())
def test_every_accepting_lasso_of_the_emptiness_check_satisfies_the_formula(f):
    buchi = translate(f)
    for prefix, loop in accepting_lassos(buchi):
        assert holds(f, prefix, loop), f"{f}: witness {prefix} ({loop})^ω"
        assert automaton_accepts(buchi, prefix, loop)


@pytest.mark.parametrize(
    ("text", "empty"),
    [("a & !a", True), ("F a & G !a", True), ("G F a & F G !a", True), ("false", True),
     ("G F a", False), ("a U b", False), ("true", False)],
)
def test_emptiness(text, empty):
    buchi = translate(text)
    assert is_empty(buchi) is empty
    witness = find_accepting_lasso(buchi)
    assert (witness is None) is empty
    if witness is not None:
        assert holds(text, *witness)


# --------------------------------------------------------------------------- golden automata

A11, A12, BOTH = frozenset({"a11"}), frozenset({"a12"}), frozenset({"a11", "a12"})


def test_golden_automaton_of_scenario_1_task():
    """`G F a11 & G F a12`: three states, deterministic, one accepting state reached only
    after both propositions have been seen since the last visit to it."""
    buchi = translate("G F a11 & G F a12")
    assert (buchi.num_states, len(buchi.initial), len(buchi.accepting)) == (3, 1, 1)
    assert buchi.atoms == ("a11", "a12")
    (init,) = buchi.initial
    (acc,) = buchi.accepting
    for q in range(3):
        for letter in (E, A11, A12, BOTH):
            assert len(buchi.successors(q, letter)) == 1  # deterministic and complete
    assert buchi.successors(init, BOTH) == (acc,)
    assert buchi.successors(acc, BOTH) == (acc,)
    # Alternating visits reach the accepting state at least once every two rounds …
    states = frozenset(buchi.initial)
    visits = []
    for letter in [A11, E, A12, E] * 4:
        states = buchi_step(buchi, states, letter)
        visits.append(acc in states)
    assert all(any(visits[i : i + 8]) for i in range(0, 9))
    # … while visiting only one of the two regions never does.
    for only in (A11, A12):
        states = frozenset(buchi.initial)
        for _ in range(6):
            states = buchi_step(buchi, states, only)
            assert acc not in states


def test_golden_automaton_of_scenario_3_task():
    """`F a1 & … & F a5`: 32 states (subsets of regions still to visit), one accepting sink."""
    buchi = translate("F a1 & F a2 & F a3 & F a4 & F a5")
    assert buchi.num_states == 32
    (acc,) = buchi.accepting
    assert buchi.edges[acc] == ((acc, buchi.alphabet.full),)  # accepting sink with `true`
    states = frozenset(buchi.initial)
    for k in range(1, 6):
        assert acc not in states
        states = buchi_step(buchi, states, frozenset({f"a{k}"}))
    assert states == {acc}


def test_literal_paper_formula_needs_both_propositions_at_once():
    buchi = translate("GF(a11 & a12)")
    assert buchi.num_states == 2
    (acc,) = buchi.accepting
    assert all(acc not in buchi.successors(q, A11) for q in range(2))
    assert all(buchi.successors(q, BOTH) == (acc,) for q in range(2))


def test_response_pattern_has_two_states():
    """`G(a -> F b)`: accepting while no request is pending (Spot's size)."""
    buchi = translate("G(a -> F b)")
    assert buchi.num_states == 2
    (init,) = buchi.initial
    assert buchi.accepting == {init}
    (pending,) = buchi.successors(init, frozenset({"a"}))
    assert pending not in buchi.accepting
    assert buchi.successors(pending, frozenset({"b"})) == (init,)
    assert buchi.successors(pending, frozenset()) == (pending,)


def test_all_accepting_automaton_is_reduced():
    """Regression (found by Hypothesis): bisimulation when every state is accepting."""
    f = parse("!F((a | !X a) R !!(b U a))")
    buchi = translate(f)
    assert buchi.accepting == set(range(buchi.num_states))
    assert automaton_accepts(buchi, [], [E]) == holds(f, [], [E])


def test_small_sizes_of_common_shapes():
    assert translate("X G F a").num_states == 2  # X of a suspendable formula is dropped
    assert translate("a & G F a").num_states == 3  # a first letter, then G F a
    assert translate("G(a -> F b) & G F c").num_states <= 4
    assert translate("G F a -> G F b").num_states <= 4


def test_buchi_step_tracks_a_violation():
    buchi = translate("G !a & F b")
    states = buchi_step(buchi, frozenset(buchi.initial), frozenset({"a"}))
    assert states == frozenset()


# --------------------------------------------------------------------------- output formats


def test_hoa_output_structure():
    buchi = translate("G F a11 & G F a12")
    text = to_hoa(buchi, name="scenario 1")
    lines = text.splitlines()
    assert lines[0] == "HOA: v1"
    assert 'name: "scenario 1"' in lines
    assert "States: 3" in lines
    assert "Start: 0" in lines
    assert 'AP: 2 "a11" "a12"' in lines
    assert "acc-name: Buchi" in lines
    assert "Acceptance: 1 Inf(0)" in lines
    assert "deterministic" in text and "complete" in text
    assert lines[-1] == "--END--"
    body = lines[lines.index("--BODY--") + 1 : -1]
    states = [line for line in body if line.startswith("State:")]
    assert len(states) == 3
    assert sum(line.endswith("{0}") for line in states) == 1
    edges = [line for line in body if line.startswith("[")]
    assert len(edges) == buchi.num_edges
    for line in edges:
        assert re.fullmatch(r"\[(t|f|!?\d+(&!?\d+)*( \| !?\d+(&!?\d+)*)*)\] \d+", line), line


def test_hoa_labels_parse_back_to_the_same_guards():
    """Read the HOA labels as LTL (0 → a11 …) and compare them with the guards letter by letter."""
    buchi = translate("F a & G (b -> X c)")
    body = to_hoa(buchi).split("--BODY--\n")[1]
    state = -1
    k = 0
    for line in body.splitlines():
        if line.startswith("State:"):
            state = int(line.split()[1])
            k = 0
        elif line.startswith("["):
            label, dst = line[1:].split("] ")
            ltl = re.sub(r"\d+", lambda m: buchi.atoms[int(m.group())], label)
            ltl = ltl.replace("t", "true") if ltl == "t" else ltl
            edge_dst, guard = buchi.edges[state][k]
            assert int(dst) == edge_dst
            for v in range(1 << len(buchi.atoms)):
                letter = frozenset(a for i, a in enumerate(buchi.atoms) if v >> i & 1)
                assert holds(ltl, [letter], [E]) == guard_holds(guard, v)
            k += 1


def test_text_and_dot_renderings():
    buchi = translate("F a & G !b")
    text = to_text(buchi)
    assert "2 states" in text and "(initial)" in text and "(accepting)" in text
    assert "a & !b" in text
    dot = to_dot(buchi)
    assert dot.startswith('digraph "buchi" {') and dot.rstrip().endswith("}")
    assert dot.count("doublecircle") == len(buchi.accepting)
    assert dot.count(" -> ") == buchi.num_edges + len(buchi.initial)


def test_translate_accepts_text_and_reports_syntax_errors():
    from tlfleet.bus.errors import FormulaSyntaxError

    assert translate("G F a").num_states == translate(parse("G F a")).num_states
    with pytest.raises(FormulaSyntaxError, match="column 4"):
        translate("G F")


def test_translation_does_not_depend_on_string_hashing(tmp_path):
    """State numbering is part of the API (replanning passes Büchi states around)."""
    import os
    import subprocess
    import sys

    script = (
        "from tlfleet.agent.ltl.buchi import translate; from tlfleet.agent.ltl.hoa import to_hoa; "
        "print(''.join(to_hoa(translate(f)) for f in "
        "['G F a21 & G F a22', 'F a1 & F a2 & F a3', 'G(a -> F b) & G F c | X(d U e)']))"
    )
    outputs = set()
    for seed in ("1", "2", "3"):
        env = {**os.environ, "PYTHONHASHSEED": seed}
        done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                              text=True, check=True, timeout=60)
        outputs.add(done.stdout)
    assert len(outputs) == 1


def test_too_many_propositions_is_a_clear_error():
    from tlfleet.agent.ltl.guards import MAX_ATOMS, TooManyPropositions
    from tlfleet.bus.errors import TlfleetError

    text = "G(" + " | ".join(f"p{i}" for i in range(MAX_ATOMS + 1)) + ")"
    with pytest.raises(TooManyPropositions, match=f"has {MAX_ATOMS + 1} atomic propositions"):
        translate(text)
    assert issubclass(TooManyPropositions, TlfleetError)


@pytest.mark.parametrize("n", [21, 40, 64])
def test_many_propositions_translate_and_accept_the_right_words(n):
    """Symbolic guards: 21–64 atoms (a truth table would need 2^n bits per guard)."""
    ps = [f"p{i}" for i in range(n)]
    f = parse("G(" + " | ".join(ps) + ") & F(" + " & ".join(ps) + ")")
    buchi = translate(f)
    assert buchi.num_states == 2
    every = frozenset(ps)
    one = frozenset({ps[-1]})
    for prefix, loop in [([], [every]), ([one], [every]), ([], [one]), ([every], [frozenset()]),
                         ([one, one], [one, every])]:
        assert automaton_accepts(buchi, prefix, loop) == holds(f, prefix, loop)
        assert accepts_lasso(buchi, prefix, loop) == holds(f, prefix, loop)


def test_valid_and_unsatisfiable_formulas_collapse_to_one_state():
    for text in ("G p0 | F !p0", "a U b | !b W (!a & !b)", "G F a | F G !a"):
        buchi = translate(text)
        assert buchi.num_states == 1 and buchi.accepting == {0}
        assert buchi.edges[0] == ((0, buchi.alphabet.full),)
    for text in ("G p0 & F !p0", "F G a & G F !a"):
        assert translate(text).num_states == 1 and not translate(text).accepting


@settings(max_examples=examples(500), deadline=None)
@given(formulas(), st.lists(lasso_words(), min_size=1, max_size=3))
def test_accepts_lasso_equals_the_independent_networkx_check(f, words):
    """tlfleet.agent.ltl.emptiness.accepts_lasso (the run report's check) against the test helper's
    networkx product, and both against exact evaluation."""
    buchi = translate(f)
    for prefix, loop in words:
        expected = holds(f, prefix, loop)
        assert automaton_accepts(buchi, prefix, loop) == expected
        assert accepts_lasso(buchi, prefix, loop) == expected, f"{f} on {prefix} ({loop})^ω"


def test_accepts_lasso_needs_a_loop():
    with pytest.raises(ValueError, match="loop of a lasso word must not be empty"):
        accepts_lasso(translate(parse("G F a")), [frozenset({"a"})], [])
