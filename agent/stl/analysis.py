"""Static analysis of ψ: concavity (paper Assumption 1) and the supremum ρ_opt (stl-funnel.md §3).

Concavity rule (conservative, documented choice)
------------------------------------------------
Each scalar expression gets a curvature in the states of the *controlled* robots; the states of the
robots listed as ``exogenous`` (LTL robots whose motion the STL agents cannot influence,
e.g. robot 1 in Scenario 3) are treated as time-varying parameters, i.e. constants:

* numbers and exogenous states: constant; controlled states ``x3``, ``y3``, ``th3``, ``p3``: affine;
* sums keep curvature (affine + convex = convex, convex + concave = unknown); ``−e`` swaps
  convex/concave; a product or quotient is only analysed when one factor (the divisor) is a
  number literal, whose sign decides the result (a product with an exogenous parameter keeps
  *affine* only);
* ``norm(v)``, ``dist(a, b)``, ``abs(e)`` of an affine argument are convex;
  ``angdist(a, b)`` of an affine difference is treated as convex (it is |a − b| on the branch
  |a − b| < π where the controller operates; the wrap is a reparametrisation of the circle);
* ``sin``/``cos`` of a non-constant argument, and anything not covered above: unknown.

A predicate μ (robustness h) is certified when h is constant, affine or concave; a negated predicate
¬μ (robustness −h) when h is constant, affine or convex. Anything else is reported by
:func:`non_concave_literals` (and warned about by ``tlfleet.agent.stl.task``). ``dist(...) >= c`` is
therefore reported (convex, not concave), ``dist(...) <= c`` is not.

Supremum
--------
:func:`literal_sup` bounds sup ρ^μ over all states by interval arithmetic: norms, distances and
``abs`` lie in [0, ∞), ``angdist`` in [0, π], ``sin``/``cos`` in [−1, 1], states in (−∞, ∞). For
``c − ‖·‖`` this gives exactly c. It is an upper bound in general (≥ the true supremum),
which is what the funnel needs; ``math.inf`` means unbounded (give ρ_opt explicitly).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Literal

from tlfleet.agent.stl.syntax import (
    BinOp,
    Call,
    Const,
    Expr,
    Neg,
    Not,
    Position,
    Predicate,
    Psi,
    StateVar,
    VecLit,
    literals,
    predicate_function,
)

Curvature = Literal["const", "affine", "convex", "concave", "unknown"]

_ADD = {
    ("affine", "affine"): "affine",
    ("affine", "convex"): "convex",
    ("affine", "concave"): "concave",
    ("convex", "convex"): "convex",
    ("concave", "concave"): "concave",
}
_FLIP = {"convex": "concave", "concave": "convex"}


def _add(a: Curvature, b: Curvature) -> Curvature:
    if a == "const":
        return b
    if b == "const":
        return a
    return _ADD.get((a, b)) or _ADD.get((b, a)) or "unknown"


def _scale(curv: Curvature, sign: float) -> Curvature:
    if sign == 0 or curv == "const":
        return "const"
    return curv if sign > 0 else _FLIP.get(curv, curv)


def literal_value(expr: Expr) -> float | None:
    """Value of an expression built from numbers only; ``None`` if it involves a state."""
    match expr:
        case Const(value):
            return value
        case Neg(arg):
            value = literal_value(arg)
            return None if value is None else -value
        case BinOp(op, left, right):
            lv, rv = literal_value(left), literal_value(right)
            if lv is None or rv is None:
                return None
            if op == "+":
                return lv + rv
            if op == "-":
                return lv - rv
            if op == "*":
                return lv * rv
            return lv / rv if rv != 0 else None
        case Call("sin" | "cos" | "abs" as func, (arg,)):
            value = literal_value(arg)
            if value is None:
                return None
            return {"sin": math.sin, "cos": math.cos, "abs": abs}[func](value)
    return None


def curvature(expr: Expr, exogenous: frozenset[int] = frozenset()) -> Curvature:
    """Curvature of ``expr`` in the controlled states (module docstring). Vectors: componentwise."""
    match expr:
        case Const():
            return "const"
        case StateVar(robot, _) | Position(robot):
            return "const" if robot in exogenous else "affine"
        case VecLit(x, y):
            cx, cy = curvature(x, exogenous), curvature(y, exogenous)
            if cx == cy == "const":
                return "const"
            return "affine" if {cx, cy} <= {"const", "affine"} else "unknown"
        case Neg(arg):
            return _scale(curvature(arg, exogenous), -1.0)
        case BinOp("+", left, right):
            return _add(curvature(left, exogenous), curvature(right, exogenous))
        case BinOp("-", left, right):
            return _add(curvature(left, exogenous), _scale(curvature(right, exogenous), -1.0))
        case BinOp("*", left, right):
            cl, cr = curvature(left, exogenous), curvature(right, exogenous)
            if cl == "const" and cr == "const":
                return "const"
            for factor, c_factor, c_other in ((left, cl, cr), (right, cr, cl)):
                if c_factor != "const":
                    continue
                value = literal_value(factor)
                if value is not None:
                    return _scale(c_other, value)
                return "affine" if c_other == "affine" else "unknown"
            return "unknown"
        case BinOp("/", left, right):
            cl, cr = curvature(left, exogenous), curvature(right, exogenous)
            if cr != "const":
                return "unknown"
            if cl == "const":
                return "const"
            value = literal_value(right)
            if value is not None and value != 0:
                return _scale(cl, value)
            return "affine" if cl == "affine" else "unknown"
        case Call("sin" | "cos", (arg,)):
            return "const" if curvature(arg, exogenous) == "const" else "unknown"
        case Call("abs" | "norm", (arg,)):
            return _convex_of_affine(curvature(arg, exogenous))
        case Call("dist" | "angdist", (a, b)):
            return _convex_of_affine(_add(curvature(a, exogenous),
                                          _scale(curvature(b, exogenous), -1.0)))
    return "unknown"


def _convex_of_affine(inner: Curvature) -> Curvature:
    if inner == "const":
        return "const"
    return "convex" if inner == "affine" else "unknown"


def is_certified_concave(literal: Predicate | Not, exogenous: frozenset[int] = frozenset()) -> bool:
    """Whether the robustness of μ (h) or ¬μ (−h) is certified concave by the rule above."""
    if isinstance(literal, Not):
        return curvature(predicate_function(literal.pred), exogenous) in ("const", "affine",
                                                                          "convex")
    return curvature(predicate_function(literal), exogenous) in ("const", "affine", "concave")


def non_concave_literals(psi: Psi, exogenous: Iterable[int] = ()) -> tuple[Predicate | Not, ...]:
    """The conjuncts of ψ whose robustness is not certified concave (Assumption 1)."""
    exo = frozenset(exogenous)
    return tuple(lit for lit in literals(psi) if not is_certified_concave(lit, exo))


# --------------------------------------------------------------------------- bounds

Interval = tuple[float, float]


def _mul(a: Interval, b: Interval) -> Interval:
    products = []
    for x in a:
        for y in b:
            products.append(0.0 if x == 0 or y == 0 else x * y)
    return min(products), max(products)


def _interval(expr: Expr) -> Interval | tuple[Interval, Interval]:
    value = literal_value(expr) if not isinstance(expr, VecLit) else None
    if value is not None:
        return value, value
    inf = math.inf
    match expr:
        case StateVar():
            return -inf, inf
        case Position():
            return (-inf, inf), (-inf, inf)
        case VecLit(x, y):
            return _interval(x), _interval(y)
        case Neg(arg):
            inner = _interval(arg)
            if isinstance(inner[0], tuple):
                return tuple((-hi, -lo) for lo, hi in inner)
            return -inner[1], -inner[0]
        case BinOp(op, left, right):
            li, ri = _interval(left), _interval(right)
            lvec, rvec = isinstance(li[0], tuple), isinstance(ri[0], tuple)
            if lvec or rvec:
                lc = li if lvec else (li, li)
                rc = ri if rvec else (ri, ri)
                return tuple(_scalar_op(op, lc[k], rc[k]) for k in range(2))
            return _scalar_op(op, li, ri)
        case Call("sin" | "cos", _):
            return -1.0, 1.0
        case Call("abs" | "norm" | "dist", _):
            return 0.0, inf
        case Call("angdist", _):
            return 0.0, math.pi
    return -inf, inf


def _scalar_op(op: str, a: Interval, b: Interval) -> Interval:
    if op == "+":
        return a[0] + b[0], a[1] + b[1]
    if op == "-":
        return a[0] - b[1], a[1] - b[0]
    if op == "*":
        return _mul(a, b)
    if b[0] <= 0 <= b[1]:
        return -math.inf, math.inf
    return _mul(a, (1.0 / b[1], 1.0 / b[0]))


def literal_sup(literal: Predicate | Not) -> float:
    """Upper bound of sup ρ over all states for μ (sup h) or ¬μ (−inf h); may be ``math.inf``."""
    pred = literal.pred if isinstance(literal, Not) else literal
    lo, hi = _interval(predicate_function(pred))
    result = -lo if isinstance(literal, Not) else hi
    return math.inf if math.isnan(result) else float(result)
