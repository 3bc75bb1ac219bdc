"""Parser and printer (ltl-planning.md §1): precedence, aliases, errors, print∘parse = id."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from ltl_helpers import formulas

from agent.errors import FormulaSyntaxError
from agent.ltl.formula import (
    FALSE,
    TRUE,
    And,
    Atom,
    Equiv,
    Finally,
    Globally,
    Implies,
    Next,
    Not,
    Or,
    Release,
    StrongRelease,
    Until,
    WeakUntil,
    Xor,
    atoms,
)
from agent.ltl.parser import parse
from agent.ltl.printer import to_string

a, b, c = Atom("a"), Atom("b"), Atom("c")

PARSES = [
    ("a", a),
    ("true", TRUE),
    ("false", FALSE),
    ("1 & 0", And((TRUE, FALSE))),
    ("a & b & c", And((And((a, b)), c))),
    ("a | b & c", Or((a, And((b, c))))),
    ("a xor b | c", Xor(a, Or((b, c)))),
    ("a -> b -> c", Implies(a, Implies(b, c))),
    ("a <-> b -> c", Equiv(a, Implies(b, c))),
    ("a -> b <-> c", Equiv(Implies(a, b), c)),
    ("a <-> b <-> c", Equiv(a, Equiv(b, c))),
    ("a U b U c", Until(a, Until(b, c))),
    ("a U b & c", And((Until(a, b), c))),
    ("!a U b", Until(Not(a), b)),
    ("F a U b", Until(Finally(a), b)),
    ("X a R b", Release(Next(a), b)),
    ("a V b", Release(a, b)),
    ("a W b", WeakUntil(a, b)),
    ("a M b", StrongRelease(a, b)),
    ("[]<> a && <>b || a", Or((And((Globally(Finally(a)), Finally(b))), a))),
    ("GFa", Globally(Finally(a))),
    ("G F a11 & G F a12", And((Globally(Finally(Atom("a11"))), Globally(Finally(Atom("a12")))))),
    ("!(a & b)", Not(And((a, b)))),
    ("  ( ( a ) )  ", a),
    ("a_1 & _x", And((Atom("a_1"), Atom("_x")))),
]


@pytest.mark.parametrize(("text", "tree"), PARSES)
def test_parse_builds_the_expected_tree(text, tree):
    assert parse(text) == tree


@pytest.mark.parametrize(("text", "tree"), PARSES)
def test_printed_form_reparses_to_the_same_tree(text, tree):
    assert parse(to_string(tree)) == tree


PRINTS = [
    ("G F a11 & G F a12", "G F a11 & G F a12"),
    ("F(a1 & F(a2 & F a3))", "F(a1 & F(a2 & F a3))"),
    ("a & (b & c)", "a & (b & c)"),
    ("(a & b) & c", "a & b & c"),
    ("(a U b) U c", "(a U b) U c"),
    ("a V b", "a R b"),
    ("<>[] a", "F G a"),
    # Spot binds xor tighter than |, and -> with <-> on one level: always bracket those.
    ("a xor (b | c)", "a xor (b | c)"),
    ("(a xor b) | c", "(a xor b) | c"),
    ("a <-> (b -> c)", "a <-> (b -> c)"),
    ("!(a -> b)", "!(a -> b)"),
]


@pytest.mark.parametrize(("text", "printed"), PRINTS)
def test_printer_output(text, printed):
    assert to_string(parse(text)) == printed
    assert str(parse(text)) == printed


BAD = [
    ("", 1, r"column 1: expected a formula, got end of input"),
    ("a &", 4, r"column 4: expected a formula after '&', got end of input"),
    ("a & & b", 5, r"column 5: expected a formula after '&', got '&'"),
    ("(a", 3, r"column 3: expected '\)' to close '\(' at column 1, got end of input"),
    ("a b", 3, r"column 3: expected an operator or end of input, got 'b'"),
    ("a)", 2, r"column 2: expected an operator or end of input, got '\)'"),
    (")", 1, r"column 1: expected a formula, got '\)'"),
    ("()", 2, r"column 2: expected a formula inside '\(', got '\)'"),
    ("A", 1, r"column 1: unknown operator 'A' \(atoms are lower-case"),
    ("a $ b", 3, r"column 3: unexpected character '\$'"),
    ("a < b", 3, r"column 3: unexpected character '<'"),
    ("a U", 4, r"column 4: expected a formula after 'U', got end of input"),
    ("G", 2, r"column 2: expected a formula after 'G', got end of input"),
    ("U a", 1, r"column 1: expected a formula, got 'U'"),
    ("a -> ", 6, r"column 6: expected a formula after '->', got end of input"),
    ("F (a | )", 8, r"column 8: expected a formula after '\|', got '\)'"),
    ("12", 1, r"column 1: unexpected character '1'"),
]


@pytest.mark.parametrize(("text", "column", "message"), BAD)
def test_bad_formulas_name_column_and_expectation(text, column, message):
    with pytest.raises(FormulaSyntaxError, match=message) as info:
        parse(text)
    assert info.value.column == column
    assert info.value.text == text


def test_syntax_error_is_a_value_error_with_a_pointer():
    with pytest.raises(ValueError, match=r"\n  a & & b\n      \^"):
        parse("a & & b")


def test_atoms_of_a_formula():
    assert atoms(parse("G F a11 & (b U !c) & X true")) == {"a11", "b", "c"}


@settings(max_examples=500, deadline=None)
@given(formulas())
def test_print_parse_round_trip(f):
    text = to_string(f)
    assert parse(text) == f
    assert to_string(parse(text)) == text
