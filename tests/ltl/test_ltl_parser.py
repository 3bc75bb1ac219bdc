"""Parser and printer (ltl-planning.md §1): precedence, aliases, errors, print∘parse = id."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from ltl_helpers import formulas
from tlfleet.agent.ltl.formula import (
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
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.ltl.printer import to_string
from tlfleet.bus.errors import FormulaSyntaxError, TlfleetError

a, b, c = Atom("a"), Atom("b"), Atom("c")

PARSES = [
    ("a", a),
    ("true", TRUE),
    ("false", FALSE),
    ("1 & 0", And((TRUE, FALSE))),
    ("a & b & c", And((a, b, c))),
    ("(a & b) & c | a & (b & c)", Or((And((a, b, c)), And((a, b, c))))),
    ("a | (b | c) | a", Or((a, b, c, a))),
    ("a | b & c", Or((a, And((b, c))))),
    ("a xor b | c", Or((Xor(a, b), c))),  # Spot: xor binds tighter than |
    ("a | b xor c", Or((a, Xor(b, c)))),
    ("a -> b -> c", Implies(a, Implies(b, c))),
    ("a <-> b -> c", Equiv(a, Implies(b, c))),
    ("a -> b <-> c", Implies(a, Equiv(b, c))),  # Spot: -> and <-> on one level, right
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
    ("a & (b & c)", "a & b & c"),  # n-ary, as in Spot
    ("(a & b) & c", "a & b & c"),
    ("(a U b) U c", "(a U b) U c"),
    ("a V b", "a R b"),
    ("<>[] a", "F G a"),
    # Spot binds xor tighter than |, and -> with <-> on one level: always bracket those.
    ("a xor (b | c)", "a xor (b | c)"),
    ("(a xor b) | c", "a xor b | c"),
    ("a <-> (b -> c)", "a <-> b -> c"),
    ("(a -> b) <-> c", "(a -> b) <-> c"),
    ('"door open" & Door', '"door open" & Door'),
    ('"a" & "Fa" & "true"', 'a & "Fa" & "true"'),
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
    ("( )", 3, r"column 3: expected a formula inside '\(', got '\)'"),
    ("()", 3, r"column 3: expected a formula after '\(\)', got end of input"),  # () is X
    ("a A", 3, r"column 3: expected an operator or end of input, got 'A'"),
    ("a $ b", 3, r"column 3: unexpected character '\$'"),
    ("a < b", 3, r"column 3: unexpected character '<'"),
    ("a U", 4, r"column 4: expected a formula after 'U', got end of input"),
    ("G", 2, r"column 2: expected a formula after 'G', got end of input"),
    ("U a", 1, r"column 1: expected a formula, got 'U'"),
    ("a -> ", 6, r"column 6: expected a formula after '->', got end of input"),
    ("F (a | )", 8, r"column 8: expected a formula after '\|', got '\)'"),
    ("12", 2, r"column 2: unexpected character '2'"),
    ("F[2] a", 4, r"F\[n:m\] expects two parameters"),
    ("F[3:1] a", 2, r"empty range \[3:1\]"),
    ('"abc', 1, r"unclosed string"),
    ("{a;b}", 1, r"PSL/SERE operator '\{' is not supported"),
    ("a |-> b", 3, r"PSL/SERE operator '\|->' is not supported"),
    ("X " * 300 + "a", 201, r"nested more than 200 levels deep"),
]


@pytest.mark.parametrize(("text", "column", "message"), BAD)
def test_bad_formulas_name_column_and_expectation(text, column, message):
    with pytest.raises(FormulaSyntaxError, match=message) as info:
        parse(text)
    assert info.value.column == column
    assert info.value.text == text


def test_syntax_error_is_one_line_naming_formula_and_column():
    with pytest.raises(TlfleetError) as info:
        parse("a & & b")
    assert str(info.value) == ("LTL formula 'a & & b', column 5: "
                               "expected a formula after '&', got '&'")
    assert isinstance(info.value, ValueError)


def test_atoms_of_a_formula():
    assert atoms(parse("G F a11 & (b U !c) & X true")) == {"a11", "b", "c"}


@settings(max_examples=examples(500), deadline=None)
@given(formulas())
def test_print_parse_round_trip(f):
    text = to_string(f)
    assert parse(text) == f
    assert to_string(parse(text)) == text


# (input, Spot's reading fully parenthesised): the precedence table of Spot's parsetl.yy
# (docs/ltl.md) — `->`/`<->` one right-associative level < `|` < `xor` < `&` < `*` <
# `U R W M` (right) < prefix `F G X !`.
SPOT_READINGS = [
    ("a -> b <-> c", "a -> (b <-> c)"),
    ("a <-> b -> c", "a <-> (b -> c)"),
    ("a <-> b <-> c", "a <-> (b <-> c)"),
    ("a -> b | c", "a -> (b | c)"),
    ("a | b -> c", "(a | b) -> c"),
    ("a | b xor c", "a | (b xor c)"),
    ("a xor b | c", "(a xor b) | c"),
    ("a xor b xor c", "(a xor b) xor c"),
    ("a xor b & c", "a xor (b & c)"),
    ("a & b xor c", "(a & b) xor c"),
    ("a & b | c & d", "(a & b) | (c & d)"),
    ("a && b || c", "(a & b) | c"),
    ("a /\\ b \\/ c", "(a & b) | c"),
    ("a + b * c", "a | (b & c)"),
    ("a & b U c", "a & (b U c)"),
    ("a U b & c", "(a U b) & c"),
    ("a U b U c", "a U (b U c)"),
    ("a U b R c W d M e", "a U (b R (c W (d M e)))"),
    ("a U b -> c", "(a U b) -> c"),
    ("F a U b", "(F a) U b"),
    ("G a R b", "(G a) R b"),
    ("X a U b", "(X a) U b"),
    ("!a U b", "(!a) U b"),
    ("!a & b", "(!a) & b"),
    ("a U F b & c", "(a U (F b)) & c"),
    ("X F G a", "X(F(G a))"),
    ("GFa", "G(F(a))"),
    ("GFaUb", "G(F(aUb))"),  # aUb is one atom where a formula is expected
    ("a Ub", "a U b"),  # …but U starts an operator where one is expected
    ("Fa0 | F1", '(F(a0)) | "F1"'),
    ("p=0 U q=1", "(!p) U q"),
    ("a V b", "a R b"),
    ("[]<>a -> <>[]b", "(G(F a)) -> (F(G b))"),
    ("F[2:3] a", "X(X(a | X a))"),
    ("G[1:4] a", "X(a & X(a & X(a & X a)))"),
    ("X[3] a", "X(X(X a))"),
    ("F[2..4] a", "X(X(a | X(a | X a)))"),
    ("G[2:$] a", "X(X(G a))"),
    ("F[1:] a", "X(F a)"),
    ("X[] a", "X(G a)"),
    ("TRUE & False", "1 & 0"),
    ('"door open" U Door', '"door open" U "Door"'),
    ("a → b ↔ c", "a -> (b <-> c)"),
    ("¬a ∧ b ∨ c", "((!a) & b) | c"),
]


@pytest.mark.parametrize(("text", "reading"), SPOT_READINGS)
def test_spot_precedence_table(text, reading):
    assert parse(text) == parse(reading)


def test_adjacent_atoms_are_an_error_as_in_spot():
    with pytest.raises(FormulaSyntaxError, match="expected an operator"):
        parse("aU b")


@settings(max_examples=examples(300), deadline=None)
@given(st.text(alphabet="abFGXUx_. 01\"\\&", min_size=1, max_size=6))
def test_any_atom_name_prints_so_that_it_parses_back(name):
    f = And((Atom(name), Globally(Atom(name))))
    assert parse(to_string(f)) == f
