"""Hypothesis strategies of random ψ expressions over three robots, shared by the gradient and the
compiled-ψ properties: scalar expressions, 2-vector expressions and the scalar shapes a predicate's
h takes (``predicate_expressions``)."""

from __future__ import annotations

from hypothesis import strategies as st
from tlfleet.agent.stl.syntax import BinOp, Call, Const, Neg, Position, StateVar, VecLit

ROBOTS = (1, 2, 3)
coords = st.floats(-3, 3, allow_nan=False)
states = st.lists(coords, min_size=9, max_size=9)  # (x, y, θ) of robots 1, 2, 3
numbers = st.floats(-2, 2, allow_nan=False).map(lambda v: round(v, 2))
scalar_leaf = st.one_of(numbers.map(Const),
                        st.builds(StateVar, st.sampled_from(ROBOTS),
                                  st.sampled_from(["x", "y", "th"])))


def _extend(children):
    return st.one_of(
        st.builds(Neg, children),
        st.builds(BinOp, st.sampled_from(["+", "-", "*"]), children, children),
        st.builds(lambda a, b: BinOp("/", a, BinOp("+", Const(3.0), Call("sin", (b,)))),
                  children, children),
        st.builds(lambda f, a: Call(f, (a,)), st.sampled_from(["sin", "cos", "abs"]), children),
        st.builds(lambda a, b: Call("angdist", (a, b)), children, children),
    )


def scalar_expressions(max_leaves: int):
    """Smooth-enough scalar expressions of the robots' states with at most ``max_leaves``."""
    return st.recursive(scalar_leaf, _extend, max_leaves=max_leaves)


def vector_expressions(scalars):
    """2-vector expressions: positions, literals of ``scalars``, and ±, scalar ×, ÷ of positions."""
    robot = st.sampled_from(ROBOTS)
    return st.one_of(
        st.builds(Position, robot),
        st.builds(VecLit, scalars, scalars),
        st.builds(lambda a, b: BinOp("-", Position(a), VecLit(b, Call("cos", (b,)))),
                  robot, scalars),
        st.builds(lambda a, b: BinOp("+", Position(a), Neg(Position(b))), robot, robot),
        st.builds(lambda c, v: BinOp("*", c, Position(v)), scalars, robot),
        st.builds(lambda v, c: BinOp("*", Position(v), c), robot, scalars),
        st.builds(lambda v, c: BinOp("/", Position(v), BinOp("+", Const(2.0),
                                                             Call("cos", (c,)))), robot, scalars),
    )


def predicate_expressions(max_leaves: int):
    """The scalar shapes of a predicate's h: a scalar expression, ‖v‖, dist(v, w) and s − ‖v‖."""
    scalars = scalar_expressions(max_leaves)
    vectors = vector_expressions(scalars)
    norms = st.builds(lambda v: Call("norm", (v,)), vectors)
    return st.one_of(
        scalars,
        norms,
        st.builds(lambda a, b: Call("dist", (a, b)), vectors, vectors),
        st.builds(lambda a, b: BinOp("-", a, b), scalars, norms),
    )
