"""Immutable syntax trees of the STL fragment (paper eq. (3), stl-funnel.md §2) and their printer.

Expressions (over robot states, x_j = [z_jᵀ, θ_j]ᵀ with z_j in m and θ_j in rad)::

    Const(c)                 a number
    StateVar(j, "x"|"y"|"th") one state component of robot j (scalar)
    Position(j)              z_j, a 2-vector
    VecLit(a, b)             [a, b], a 2-vector of scalar expressions
    Neg(e)                   −e
    BinOp(op, l, r)          l op r, op ∈ {+, −, *, /}
    Call(f, args)            f ∈ {sin, cos, abs, norm, dist, angdist}

Boolean part ψ (eq. (3a)): ``Predicate(lhs, cmp, rhs)`` (μ), ``Not(Predicate)`` (¬μ),
``And(children)`` (flattened, never nested), ``Top()`` (⊤). Temporal part φ (eq. (3b)):
``Temporal(op, a, b, body)`` with op ∈ {G, F} and absolute mission times 0 ≤ a ≤ b [s].

Nodes are frozen dataclasses with tuple children; every semantics (shape, value, gradient,
curvature, bounds) is a function over the tree elsewhere (style.md §2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Shape = Literal["scalar", "vector"]
FUNCTIONS: dict[str, tuple[int, str]] = {
    # name -> (arity, argument/result description used in error messages)
    "sin": (1, "scalar -> scalar"),
    "cos": (1, "scalar -> scalar"),
    "abs": (1, "scalar -> scalar"),
    "norm": (1, "scalar or 2-vector -> scalar"),
    "dist": (2, "two scalars or two 2-vectors -> scalar"),
    "angdist": (2, "two scalars (angles) -> scalar in [0, pi]"),
}
COMPARISONS = ("<=", "<", ">=", ">")


@dataclass(frozen=True, slots=True)
class Const:
    value: float


@dataclass(frozen=True, slots=True)
class StateVar:
    robot: int
    component: Literal["x", "y", "th"]


@dataclass(frozen=True, slots=True)
class Position:
    robot: int


@dataclass(frozen=True, slots=True)
class VecLit:
    x: Expr
    y: Expr


@dataclass(frozen=True, slots=True)
class Neg:
    arg: Expr


@dataclass(frozen=True, slots=True)
class BinOp:
    op: Literal["+", "-", "*", "/"]
    left: Expr
    right: Expr


@dataclass(frozen=True, slots=True)
class Call:
    func: str
    args: tuple[Expr, ...]


Expr = Const | StateVar | Position | VecLit | Neg | BinOp | Call


@dataclass(frozen=True, slots=True)
class Predicate:
    """μ := (h(x̄) ≥ 0) written as ``lhs cmp rhs``; see :func:`predicate_function` for h."""

    lhs: Expr
    cmp: Literal["<=", "<", ">=", ">"]
    rhs: Expr


@dataclass(frozen=True, slots=True)
class Not:
    pred: Predicate


@dataclass(frozen=True, slots=True)
class And:
    children: tuple[Predicate | Not, ...]


@dataclass(frozen=True, slots=True)
class Top:
    pass


Psi = Predicate | Not | And | Top


@dataclass(frozen=True, slots=True)
class Temporal:
    op: Literal["G", "F"]
    a: float  # [s] absolute mission time
    b: float  # [s]
    body: Psi


def predicate_function(pred: Predicate) -> Expr:
    """h of μ: ``lhs <= rhs`` and ``lhs < rhs`` give h = rhs − lhs; ``>=``, ``>`` give lhs − rhs.

    Strict and non-strict comparisons share h (robust semantics does not distinguish them).
    """
    if pred.cmp in ("<=", "<"):
        return BinOp("-", pred.rhs, pred.lhs)
    return BinOp("-", pred.lhs, pred.rhs)


def literals(psi: Psi) -> tuple[Predicate | Not, ...]:
    """The conjuncts of ψ (predicates and negated predicates), ⊤ dropped."""
    match psi:
        case And(children):
            return children
        case Top():
            return ()
        case _:
            return (psi,)


def robots_of(node: Expr | Psi | Temporal) -> frozenset[int]:
    """Ids of the robots whose states enter the node (its participants, stl-funnel.md §2)."""
    match node:
        case Const() | Top():
            return frozenset()
        case StateVar(robot, _) | Position(robot):
            return frozenset((robot,))
        case VecLit(x, y):
            return robots_of(x) | robots_of(y)
        case Neg(arg):
            return robots_of(arg)
        case BinOp(_, left, right):
            return robots_of(left) | robots_of(right)
        case Call(_, args):
            return frozenset().union(*(robots_of(a) for a in args))
        case Predicate(lhs, _, rhs):
            return robots_of(lhs) | robots_of(rhs)
        case Not(pred):
            return robots_of(pred)
        case And(children):
            return frozenset().union(*(robots_of(c) for c in children))
        case Temporal(_, _, _, body):
            return robots_of(body)
    raise TypeError(f"not an STL node: {node!r}")


# --------------------------------------------------------------------------- printer

_PRECEDENCE = {"+": 1, "-": 1, "*": 2, "/": 2}


def _number(value: float) -> str:
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def to_text(node: Expr | Psi | Temporal) -> str:
    """Canonical text of a node; ``parse_task(to_text(φ)) == φ`` (print∘parse is the identity)."""
    match node:
        case Temporal(op, a, b, body):
            return f"{op}[{_number(a)},{_number(b)}] ({to_text(body)})"
        case And(children):
            return " & ".join(_conjunct_text(c) for c in children)
        case Top():
            return "true"
        case Not(pred):
            return f"!({to_text(pred)})"
        case Predicate(lhs, cmp, rhs):
            return f"{to_text(lhs)} {cmp} {to_text(rhs)}"
        case _:
            return _expr_text(node, 0)


def _conjunct_text(node: Predicate | Not) -> str:
    return to_text(node) if isinstance(node, Not) else f"({to_text(node)})"


def _expr_text(node: Expr, parent: int) -> str:
    match node:
        case Const(value):
            text = _number(value)
            return f"({text})" if value < 0 and parent >= 2 else text
        case StateVar(robot, component):
            return f"{component}{robot}"
        case Position(robot):
            return f"p{robot}"
        case VecLit(x, y):
            return f"[{_expr_text(x, 0)}, {_expr_text(y, 0)}]"
        case Neg(arg):
            text = f"-{_expr_text(arg, 3)}"
            return f"({text})" if parent >= 2 else text
        case BinOp(op, left, right):
            prec = _PRECEDENCE[op]
            text = f"{_expr_text(left, prec)} {op} {_expr_text(right, prec + 1)}"
            return f"({text})" if prec < parent else text
        case Call(func, args):
            return f"{func}({', '.join(_expr_text(a, 0) for a in args)})"
    raise TypeError(f"not an STL expression: {node!r}")
