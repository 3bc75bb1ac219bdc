"""Hypothesis strategies of random ψ expressions over three robots, shared by the gradient and the
compiled-ψ properties (each file adds its own vector and predicate shapes)."""

from __future__ import annotations

from hypothesis import strategies as st

from agent.stl.syntax import BinOp, Call, Const, Neg, StateVar

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
