"""Evaluation of expression trees: compiled scalar closures with exact gradients, and numpy arrays.

Compiled form (control fast path, stl-funnel.md §6.1)
-----------------------------------------------------
:func:`compile_expr` turns an expression into a closure ``f(s) -> (value, grad)`` over the flat
stacked state ``s = [x_j1, y_j1, θ_j1, x_j2, …]`` (length 3P, robots in the order of ``robots``;
m and rad). Scalars give ``value: float`` and ``grad: list[float] | None`` (∂value/∂s, length
3P, ``None`` meaning identically zero); 2-vectors give ``(vx, vy)`` and ``(grad_x, grad_y)``. The
gradient is forward-mode differentiation of the tree, so it is exact. Non-differentiable points
(‖v‖ = 0, |e| at 0) get gradient 0 (stl-funnel.md §3; the authors' code zeroes non-finite
gradients). Plain floats and lists are used on purpose: for 3P ≤ 12 entries they are several
times faster than numpy arrays.

Vectorised form (monitors)
--------------------------
:func:`evaluate_array` evaluates an expression on whole trajectories: ``states[j]`` is an (N, 3)
array of robot j's (x, y, θ); scalars give (N,) arrays, vectors pairs of (N,) arrays.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from tlfleet.agent.stl.syntax import BinOp, Call, Const, Expr, Neg, Position, StateVar, VecLit

Grad = list[float] | None
ScalarFn = Callable[[Sequence[float]], tuple[float, Grad]]
COMPONENT_INDEX = {"x": 0, "y": 1, "th": 2}
_TWO_PI = 2.0 * math.pi
_TINY = 1e-150  # below this norm the gradient is taken as 0 (stl-funnel.md §3)


def wrap_angle(angle: float) -> float:
    """Angle wrapped to [−π, π] [rad]."""
    return math.remainder(angle, _TWO_PI)


def _lin(a: float, ga: Grad, b: float, gb: Grad) -> Grad:
    """a·ga + b·gb with ``None`` standing for the zero gradient."""
    if ga is None:
        if gb is None:
            return None
        return gb if b == 1.0 else [b * v for v in gb]
    if gb is None:
        return ga if a == 1.0 else [a * v for v in ga]
    return [a * u + b * v for u, v in zip(ga, gb, strict=True)]


def compile_expr(expr: Expr, robots: Sequence[int]) -> Callable:
    """Closure ``f(s) -> (value, grad)`` for ``expr`` over the stacked state of ``robots``."""
    slots = {robot: 3 * k for k, robot in enumerate(robots)}
    n = 3 * len(robots)

    def unit(k: int) -> list[float]:
        e = [0.0] * n
        e[k] = 1.0
        return e

    def build(node: Expr) -> tuple[Callable, bool]:
        """(closure, is_vector)."""
        match node:
            case Const(value):
                result = (float(value), None)
                return (lambda s: result), False
            case StateVar(robot, component):
                k = slots[robot] + COMPONENT_INDEX[component]
                e = unit(k)
                return (lambda s: (s[k], e)), False
            case Position(robot):
                kx = slots[robot]
                ky = kx + 1
                ex, ey = unit(kx), unit(ky)
                return (lambda s: ((s[kx], s[ky]), (ex, ey))), True
            case VecLit(x, y):
                fx, _ = build(x)
                fy, _ = build(y)

                def vec(s):
                    vx, gx = fx(s)
                    vy, gy = fy(s)
                    return (vx, vy), (gx, gy)

                return vec, True
            case Neg(arg):
                fa, is_vec = build(arg)
                if is_vec:
                    def neg_vec(s):
                        (vx, vy), (gx, gy) = fa(s)
                        return (-vx, -vy), (_lin(-1.0, gx, 0.0, None), _lin(-1.0, gy, 0.0, None))
                    return neg_vec, True

                def neg(s):
                    v, g = fa(s)
                    return -v, _lin(-1.0, g, 0.0, None)
                return neg, False
            case BinOp(op, left, right):
                return _binop(op, build(left), build(right))
            case Call(func, args):
                return _call(func, [build(a) for a in args]), False
        raise TypeError(f"not an STL expression: {node!r}")

    return build(expr)[0]


def _binop(op: str, left: tuple[Callable, bool], right: tuple[Callable, bool]):
    fl, lvec = left
    fr, rvec = right
    if op in ("+", "-"):
        sign = 1.0 if op == "+" else -1.0
        if lvec:
            def addsub_vec(s):
                (ax, ay), (gax, gay) = fl(s)
                (bx, by), (gbx, gby) = fr(s)
                return ((ax + sign * bx, ay + sign * by),
                        (_lin(1.0, gax, sign, gbx), _lin(1.0, gay, sign, gby)))
            return addsub_vec, True

        def addsub(s):
            a, ga = fl(s)
            b, gb = fr(s)
            return a + sign * b, _lin(1.0, ga, sign, gb)
        return addsub, False
    if op == "*":
        if not lvec and not rvec:
            def mul(s):
                a, ga = fl(s)
                b, gb = fr(s)
                return a * b, _lin(b, ga, a, gb)
            return mul, False
        fs, fv = (fl, fr) if rvec else (fr, fl)

        def scale_vec(s):
            c, gc = fs(s)
            (vx, vy), (gx, gy) = fv(s)
            return (c * vx, c * vy), (_lin(vx, gc, c, gx), _lin(vy, gc, c, gy))
        return scale_vec, True
    # division by a scalar
    if lvec:
        def div_vec(s):
            (vx, vy), (gx, gy) = fl(s)
            d, gd = fr(s)
            inv = 1.0 / d
            return ((vx * inv, vy * inv),
                    (_lin(inv, gx, -vx * inv * inv, gd), _lin(inv, gy, -vy * inv * inv, gd)))
        return div_vec, True

    def div(s):
        a, ga = fl(s)
        d, gd = fr(s)
        inv = 1.0 / d
        return a * inv, _lin(inv, ga, -a * inv * inv, gd)
    return div, False


def _norm_closure(f: Callable, is_vec: bool) -> Callable:
    if not is_vec:
        def absolute(s):
            v, g = f(s)
            if v == 0.0:
                return 0.0, None
            return abs(v), _lin(1.0 if v > 0 else -1.0, g, 0.0, None)
        return absolute

    def norm(s):
        (vx, vy), (gx, gy) = f(s)
        length = math.hypot(vx, vy)
        if length < _TINY:  # non-differentiable at 0 (and 1/length would overflow): gradient 0
            return length, None
        inv = 1.0 / length
        return length, _lin(vx * inv, gx, vy * inv, gy)
    return norm


def _call(func: str, args: list[tuple[Callable, bool]]) -> Callable:
    if func in ("sin", "cos"):
        (fa, _), = args
        if func == "sin":
            def sin(s):
                v, g = fa(s)
                return math.sin(v), _lin(math.cos(v), g, 0.0, None)
            return sin

        def cos(s):
            v, g = fa(s)
            return math.cos(v), _lin(-math.sin(v), g, 0.0, None)
        return cos
    if func in ("abs", "norm"):
        return _norm_closure(*args[0])
    if func == "dist":
        return _norm_closure(*_binop("-", args[0], args[1]))
    if func == "angdist":
        (fa, _), (fb, _) = args

        def angdist(s):
            a, ga = fa(s)
            b, gb = fb(s)
            d = math.remainder(a - b, _TWO_PI)
            if d == 0.0:
                return 0.0, None
            sign = 1.0 if d > 0 else -1.0
            return abs(d), _lin(sign, ga, -sign, gb)
        return angdist
    raise ValueError(f"unknown function {func!r}")


# --------------------------------------------------------------------------- numpy


def evaluate_array(expr: Expr, states: Mapping[int, np.ndarray]):
    """Vectorised value of ``expr``; ``states[j]``: robot j's (N, 3) array of (x, y, θ) [m, m, rad].

    Returns an (N,) array for scalars (a Python float for constant expressions), and a pair of
    them for 2-vectors.
    """
    match expr:
        case Const(value):
            return float(value)
        case StateVar(robot, component):
            return states[robot][:, COMPONENT_INDEX[component]]
        case Position(robot):
            return states[robot][:, 0], states[robot][:, 1]
        case VecLit(x, y):
            return evaluate_array(x, states), evaluate_array(y, states)
        case Neg(arg):
            value = evaluate_array(arg, states)
            return (-value[0], -value[1]) if isinstance(value, tuple) else -value
        case BinOp(op, left, right):
            a = evaluate_array(left, states)
            b = evaluate_array(right, states)
            return _array_op(op, a, b)
        case Call("sin", (arg,)):
            return np.sin(evaluate_array(arg, states))
        case Call("cos", (arg,)):
            return np.cos(evaluate_array(arg, states))
        case Call("abs" | "norm", (arg,)):
            return _array_norm(evaluate_array(arg, states))
        case Call("dist", (a, b)):
            return _array_norm(_array_op("-", evaluate_array(a, states),
                                         evaluate_array(b, states)))
        case Call("angdist", (a, b)):
            d = np.asarray(evaluate_array(a, states) - evaluate_array(b, states))
            return np.abs(np.remainder(d + math.pi, _TWO_PI) - math.pi)
    raise TypeError(f"not an STL expression: {expr!r}")


def _array_op(op: str, a, b):
    if isinstance(a, tuple) or isinstance(b, tuple):
        ax, ay = a if isinstance(a, tuple) else (a, a)
        bx, by = b if isinstance(b, tuple) else (b, b)
        return _array_op(op, ax, bx), _array_op(op, ay, by)
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    return a / b


def _array_norm(value):
    if isinstance(value, tuple):
        return np.hypot(value[0], value[1])
    return np.abs(value)
