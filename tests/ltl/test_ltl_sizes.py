"""Size targets of ltl-planning.md §2 for robot-mission families, n = 1..6, plus correctness of
those automata on words that separate them from near misses."""

from __future__ import annotations

import itertools

import pytest
from ltl_helpers import automaton_accepts
from tlfleet.agent.ltl.buchi import translate
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.ltl.parser import parse

E = frozenset()


def gf_conjunction(n: int) -> str:
    return " & ".join(f"G F a{i}" for i in range(1, n + 1))


def nested_f(n: int) -> str:
    inner = f"a{n}"
    for i in range(n - 1, 0, -1):
        inner = f"a{i} & F({inner})"
    return f"F({inner})"


def f_conjunction(n: int) -> str:
    return " & ".join(f"F a{i}" for i in range(1, n + 1))


def gf_nested(n: int) -> str:
    return f"G {nested_f(n)}"


FAMILIES = {
    "GF a1 & ... & GF an": (gf_conjunction, lambda n: n + 1),
    "F(a1 & F(a2 & ... F an))": (nested_f, lambda n: n + 1),
    "F a1 & ... & F an": (f_conjunction, lambda n: 2**n),
    "GF(a1 & F(a2 & ... F an))": (gf_nested, lambda n: n + 1),
}
CASES = [(family, n) for family in FAMILIES for n in range(1, 7)]


def letter(*indices: int) -> frozenset[str]:
    return frozenset(f"a{i}" for i in indices)


def probe_words(n: int):
    """Words that tell the families apart: in order, reversed, one atom missing, all at once."""
    in_order = [letter(i) for i in range(1, n + 1)]
    words = [
        ([], in_order),
        ([], list(reversed(in_order))),
        (in_order, [E]),
        (list(reversed(in_order)), [E]),
        ([], [letter(*range(1, n + 1))]),
        ([], [E]),
    ]
    for missing in range(1, n + 1):
        partial = [x for x in in_order if x != letter(missing)] or [E]
        words.append(([], partial))
        words.append((partial, [E]))
    return words


@pytest.mark.parametrize(("family", "n"), CASES)
def test_size_target(family, n):
    make, bound = FAMILIES[family]
    buchi = translate(make(n))
    assert buchi.num_states <= bound(n), f"{make(n)}: {buchi.num_states} states"


@pytest.mark.parametrize(("family", "n"), CASES)
def test_family_automata_are_correct(family, n):
    make, _bound = FAMILIES[family]
    text = make(n)
    buchi = translate(text)
    f = parse(text)
    for prefix, loop in probe_words(n):
        assert automaton_accepts(buchi, prefix, loop) == holds(f, prefix, loop), (
            f"{text} on {prefix} ({loop})^ω"
        )


@pytest.mark.parametrize("n", [2, 3, 4])
def test_visit_all_accepts_every_order_and_nothing_less(n):
    buchi = translate(f_conjunction(n))
    for order in itertools.permutations(range(1, n + 1)):
        assert automaton_accepts(buchi, [letter(i) for i in order], [E])
        assert not automaton_accepts(buchi, [letter(i) for i in order[:-1]], [E])


def test_sequence_needs_the_order():
    buchi = translate(nested_f(3))
    assert automaton_accepts(buchi, [letter(1), E, letter(2), letter(3)], [E])
    assert automaton_accepts(buchi, [letter(1, 2, 3)], [E])
    assert not automaton_accepts(buchi, [letter(3), letter(2), letter(1)], [E])


def test_the_known_sizes_exactly():
    """Pin today's sizes (a regression to larger automata should be noticed)."""
    assert [translate(gf_conjunction(n)).num_states for n in range(1, 7)] == [2, 3, 4, 5, 6, 7]
    assert [translate(nested_f(n)).num_states for n in range(1, 7)] == [2, 3, 4, 5, 6, 7]
    assert [translate(gf_nested(n)).num_states for n in range(1, 7)] == [2, 3, 4, 5, 6, 7]
    assert [translate(f_conjunction(n)).num_states for n in range(1, 7)] == [
        2, 4, 8, 16, 32, 64
    ]
