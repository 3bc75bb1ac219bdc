"""Parser of STL sub-tasks: every scenario form, the printed form round-trips, pinned errors."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from tlfleet.agent.stl.parser import parse_psi, parse_task
from tlfleet.agent.stl.syntax import (
    And,
    BinOp,
    Call,
    Const,
    Neg,
    Not,
    Position,
    Predicate,
    StateVar,
    Temporal,
    Top,
    VecLit,
    predicate_function,
    robots_of,
    to_text,
)
from tlfleet.bus.errors import FormulaSyntaxError

SCENARIO_TASKS = [
    "G[21,30] (dist(p3, [0,-2]) <= 0.1)",
    "F[57,58] (dist(p3, [1.5,-1.5]) <= 0.1 & dist(p3, p4) <= 0.7)",
    "G[5,30] (dist(p4, p3) <= 1 & dist(p4, p5) <= 1)",
    "F[83,87] (dist(p4, [2,2]) <= 0.1)",
    "G[21,30] (dist(p5, [0,2]) <= 0.1)",
    "F[44,47] (dist(p5, [-1,0.5]) <= 0.1)",
    "G[0,90] (dist(p3, p1) <= 0.6)",
    "G[0,90] (dist(p4, p2) <= 0.6)",
    "G[10,100] (dist(p2 - p1, [sin(th1), -cos(th1)]) <= 0.1 & angdist(th2, th1) <= 0.09)",
    "G[10,100] (dist(p3 - p1, [-sin(th1), cos(th1)]) <= 0.1 & angdist(th3, th1) <= 0.09)",
    "G[10,100] (dist(p4 - p1, [-cos(th1), -sin(th1)]) <= 0.1 & angdist(th4, th1) <= 0.09)",
]


@pytest.mark.parametrize("text", SCENARIO_TASKS)
def test_every_scenario_task_parses_and_round_trips(text):
    phi = parse_task(text, robot_ids=[1, 2, 3, 4, 5])
    assert isinstance(phi, Temporal)
    assert parse_task(to_text(phi)) == phi


def test_tree_of_a_conjunction():
    phi = parse_task("F[57,58] (dist(p3, [1.5,-1.5]) <= 0.1 & dist(p3, p4) <= 0.7)")
    assert phi == Temporal("F", 57.0, 58.0, And((
        Predicate(Call("dist", (Position(3), VecLit(Const(1.5), Const(-1.5)))), "<=", Const(0.1)),
        Predicate(Call("dist", (Position(3), Position(4))), "<=", Const(0.7)),
    )))
    assert robots_of(phi) == {3, 4}


def test_formation_tree_and_predicate_function():
    phi = parse_task("G[10,100] (dist(p2 - p1, [sin(th1), -cos(th1)]) <= 0.1)")
    pred = phi.body
    assert pred.lhs == Call("dist", (BinOp("-", Position(2), Position(1)),
                                     VecLit(Call("sin", (StateVar(1, "th"),)),
                                            Neg(Call("cos", (StateVar(1, "th"),))))))
    assert predicate_function(pred) == BinOp("-", Const(0.1), pred.lhs)
    geq = parse_task("G[0,1] x3 >= 2").body
    assert predicate_function(geq) == BinOp("-", StateVar(3, "x"), Const(2.0))


def test_negation_precedence_top_and_flattening():
    psi = parse_psi("!(x1 <= 1) & (y1 > 0 & true) & ((th1 < 3))")
    assert psi == And((Not(Predicate(StateVar(1, "x"), "<=", Const(1.0))),
                       Predicate(StateVar(1, "y"), ">", Const(0.0)),
                       Predicate(StateVar(1, "th"), "<", Const(3.0))))
    assert parse_psi("true") == Top()
    assert parse_psi("(x1 + 1) * 2 <= -3 / 4 - -x2").lhs == BinOp(
        "*", BinOp("+", StateVar(1, "x"), Const(1.0)), Const(2.0))
    assert parse_psi("x1 <= pi").rhs == Const(math.pi)
    assert parse_task("G[0,1e1] x1 <= 2.5e-1") == Temporal(
        "G", 0.0, 10.0, Predicate(StateVar(1, "x"), "<=", Const(0.25)))


# The error table: (text, column, message regex).
ERRORS = [
    ("", 1, r"expected 'G\[a,b\]' or 'F\[a,b\]' at the start of the task, found end of formula"),
    ("H[1,2] x1 <= 0", 1, r"expected 'G\[a,b\]' or 'F\[a,b\]' at the start of the task, found 'H'"),
    ("G(1,2) x1 <= 0", 2, r"expected '\[' after 'G', found '\('"),
    ("G[a,2] x1 <= 0", 3, r"expected a number for the window start a, found 'a'"),
    ("G[1 2] x1 <= 0", 5, r"expected ',' between the window bounds, found '2'"),
    ("G[1,2 x1 <= 0", 7, r"expected '\]' closing the time window, found 'x1'"),
    ("G[5,3] x1 <= 0", 3, r"time window \[5, 3\] needs 0 <= a <= b"),
    ("G[-1,3] x1 <= 0", 3, r"time window \[-1, 3\] needs 0 <= a <= b"),
    ("G[0,1] x1 <= 0 | y1 <= 0", 16, r"'\|' \(disjunction\) is not in the STL fragment"),
    ("G[0,1] (x1 <= 0 | y1 <= 0)", 17, r"'\|' \(disjunction\) is not in the STL fragment"),
    ("G[0,1] x1 <= 0 && y1 <= 0", 16, r"use '&' for conjunction"),
    ("G[0,1] x1 = 0", 11, r"'=' is not one"),
    ("G[0,1] x1", 10, r"expected a comparison \(<=, <, >=, >\) after the expression, "
                      r"found end of formula"),
    ("G[0,1] x1 <= ", 14, r"expected a number, a robot state .* found end of formula"),
    ("G[0,1] F[0,1] x1 <= 0", 8, r"nested temporal operators are not in the STL fragment"),
    ("G[0,1] !(x1 <= 0 & x2 <= 0)", 8, r"negation applies to a single predicate"),
    ("G[0,1] p1 <= 1", 8, r"comparison needs scalar sides; the left side is a 2-vector"),
    ("G[0,1] 1 >= p1 + [1, 2]", 13, r"the right side is a 2-vector"),
    ("G[0,1] x1 + p1 <= 1", 11, r"cannot add a scalar and a 2-vector"),
    ("G[0,1] norm(p1 * p2) <= 1", 16, r"cannot multiply two 2-vectors"),
    ("G[0,1] norm(1 / p2) <= 1", 15, r"cannot divide by a 2-vector"),
    ("G[0,1] sin(p1) <= 1", 8, r"sin expects scalar arguments"),
    ("G[0,1] dist(p1, x2) <= 1", 8, r"dist expects two arguments of the same shape"),
    ("G[0,1] dist(p1) <= 1", 8, r"dist takes 2 arguments .* got 1"),
    ("G[0,1] tan(x1) <= 1", 8, r"unknown function 'tan' \(known: sin, cos, abs, norm, dist, "
                               r"angdist\)"),
    ("G[0,1] z1 <= 1", 8, r"unknown name 'z1': expected p<id>, x<id>, y<id>, th<id>"),
    ("G[0,1] [x1, p2] <= 1", 13, r"vector components must be scalars"),
    ("G[0,1] x1 <= 1 $", 16, r"unexpected character '\$'"),
    ("G[0,1] (x1 <= 1", 16, r"expected '\)' closing the parenthesis, found end of formula"),
    ("G[0,1] x1 <= 1 x2", 16, r"expected '&' or end of formula, found 'x2'"),
    ("G[0,1] dist(p7, p1) <= 1", 13, r"robot 7 is not in the scenario \(robots: 1, 2, 3\)"),
    ("G[0,1] x9 >= 0", 8, r"robot 9 is not in the scenario"),
]


@pytest.mark.parametrize(("text", "column", "message"), ERRORS)
def test_parse_errors_name_column_and_expectation(text, column, message):
    with pytest.raises(FormulaSyntaxError, match=message) as info:
        parse_task(text, robot_ids=[1, 2, 3])
    assert info.value.column == column
    assert f"column {column}:" in str(info.value)


# --------------------------------------------------------------------------- print ∘ parse = id

robots = st.integers(1, 4)
numbers = st.floats(-5, 5, allow_nan=False).map(lambda v: round(v, 3))
scalar_leaf = st.one_of(numbers.map(Const), st.builds(StateVar, robots,
                                                      st.sampled_from(["x", "y", "th"])))
vector_leaf = st.one_of(st.builds(Position, robots))


def _scalars(children):
    return st.one_of(
        st.builds(Neg, children.filter(lambda e: not isinstance(e, Const))),
        st.builds(BinOp, st.sampled_from(["+", "-", "*", "/"]), children, children),
        st.builds(lambda f, a: Call(f, (a,)), st.sampled_from(["sin", "cos", "abs"]), children),
        st.builds(lambda a, b: Call("angdist", (a, b)), children, children),
    )


scalar_exprs = st.recursive(scalar_leaf, _scalars, max_leaves=6)
vector_exprs = st.one_of(
    vector_leaf,
    st.builds(VecLit, scalar_exprs, scalar_exprs),
    st.builds(lambda a, b: BinOp("-", a, b), vector_leaf, st.builds(VecLit, scalar_exprs,
                                                                    scalar_exprs)),
)
norms = st.one_of(st.builds(lambda v: Call("norm", (v,)), vector_exprs),
                  st.builds(lambda a, b: Call("dist", (a, b)), vector_exprs, vector_exprs))
sides = st.one_of(scalar_exprs, norms)
predicates = st.builds(Predicate, sides, st.sampled_from(["<=", "<", ">=", ">"]), sides)
literals_ = st.one_of(predicates, st.builds(Not, predicates))
psis = st.one_of(literals_, st.lists(literals_, min_size=2, max_size=4).map(
    lambda xs: And(tuple(xs))))


@given(op=st.sampled_from(["G", "F"]), a=st.integers(0, 50), length=st.integers(0, 50), psi=psis)
def test_print_then_parse_is_identity(op, a, length, psi):
    phi = Temporal(op, float(a), float(a + length), psi)
    assert parse_task(to_text(phi)) == phi
