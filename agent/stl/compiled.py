"""ψ compiled once into straight-line Python: the control step's ρ^ψ and ∂ρ^ψ/∂x̄.

The generic evaluator (``tlfleet.agent.stl.evaluate.compile_expr`` +
``tlfleet.agent.stl.robustness.CompiledPsi``) walks a tree of closures at every step, allocating a
tuple and a full-length gradient list per node. Here the same tree is translated **once per
sub-task** into the source of one function
``value_grad(s) -> (ρ, ∂ρ/∂s)`` over the stacked state ``s = [x_j1, y_j1, θ_j1, …]`` (m, rad) and
compiled with :func:`compile`; it computes

    ρ^μ = h(x̄),   ρ^¬μ = −h(x̄),   ρ^{ψ1∧…∧ψn} = m − (1/η)·ln Σ_k exp(−η(ρ_k − m)),  m = min_k ρ_k
    ∂ρ/∂s = Σ_k w_k ∂ρ_k/∂s,   w_k = exp(−η(ρ_k − m)) / Σ_l exp(−η(ρ_l − m))

(paper §II-B; stl-funnel.md §3), with forward-mode derivatives of every node as in the generic
evaluator (non-differentiable points ‖v‖ = 0, |e| = 0, wrap(a − b) = 0 give gradient 0).

**Same floats as the generic evaluator.** The generated code performs the generic evaluator's
floating-point operations in the generic order; it only drops the terms that are a structural
zero (a gradient entry no state enters, e.g. ∂/∂θ of a distance) and multiplications by the
literals ±1.0 (exact in IEEE 754). Adding a structural zero ``x·0.0`` can only change the sign
of an exact zero result (or give NaN where the generic gives ±∞·0), so every non-zero value and
gradient entry is bit-identical to the generic one; the control law cannot tell −0.0 from 0.0
(``tlfleet.agent.stl.control_law`` squares the gradient, and eq. (6) adds β·ū_col), which keeps the
lockstep trajectories byte-identical. ``tests/stl/test_stl_compiled.py`` checks
compiled = generic (to 1e-12, and bit-for-bit on non-zero entries) on random states and random
expression trees.

:class:`StraightLinePsi` has the interface of ``CompiledPsi``; only ``value_grad`` (the control
path) is generated, the monitors' ``value``/``value_min`` and ``literal_values_grads`` are the
generic reference's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from tlfleet.agent.stl.evaluate import COMPONENT_INDEX, Grad
from tlfleet.agent.stl.robustness import CompiledPsi
from tlfleet.agent.stl.syntax import (
    BinOp,
    Call,
    Const,
    Expr,
    Neg,
    Not,
    Position,
    Psi,
    StateVar,
    VecLit,
    literals,
    predicate_function,
)

_TINY = 1e-150  # as tlfleet.agent.stl.evaluate: below this norm the gradient is taken as 0
_ONE = "1.0"  # the literal 1.0 (a unit gradient entry); products with it are exact identities

SparseGrad = dict[int, str]  # stacked-state index -> Python expression; missing = structural zero


class _Emitter:
    """Lines of the generated function and fresh local names."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self._count = 0
        self.state_reads: dict[int, str] = {}

    def fresh(self, prefix: str = "v") -> str:
        self._count += 1
        return f"{prefix}{self._count}"

    def let(self, expr: str, prefix: str = "v") -> str:
        if _is_atom(expr):
            return expr
        name = self.fresh(prefix)
        self.lines.append(f"{name} = {expr}")
        return name

    def state(self, k: int) -> str:
        name = self.state_reads.get(k)
        if name is None:
            name = self.state_reads[k] = f"s{k}"
        return name


def _is_atom(expr: str) -> bool:
    return expr.isidentifier() or _is_literal(expr)


def _is_literal(expr: str) -> bool:
    try:
        float(expr)
    except ValueError:
        return False
    return True


def _literal(value: float) -> str:
    if math.isnan(value):
        return "_NAN"
    if math.isinf(value):
        return "_INF" if value > 0 else "(-_INF)"
    return repr(float(value))


def _times(a: str, g: str) -> str:
    """``a * g`` with the exact identities 1.0·g = g, a·1.0 = a and (−1.0)·g = −g."""
    if g == _ONE:
        return a
    if a == _ONE:
        return g
    if a == "-1.0":
        return f"(-{g})"
    return f"{a} * {g}"


def _lin(em: _Emitter, a: str, ga: SparseGrad, b: str, gb: SparseGrad) -> SparseGrad:
    """a·ga + b·gb entry by entry, as ``tlfleet.agent.stl.evaluate._lin`` computes it."""
    out: SparseGrad = {}
    for k in sorted(ga.keys() | gb.keys()):
        if k in ga and k in gb:
            out[k] = em.let(f"{_times(a, ga[k])} + {_times(b, gb[k])}", "g")
        elif k in ga:
            out[k] = ga[k] if a == _ONE else em.let(_times(a, ga[k]), "g")
        else:
            out[k] = gb[k] if b == _ONE else em.let(_times(b, gb[k]), "g")
    return out


def _zeroed(em: _Emitter, grads: Sequence[SparseGrad]) -> tuple[list[SparseGrad], list[str]]:
    """Fresh variables for the entries of ``grads``; returns them and the names (so that a
    runtime branch can set them all to 0.0 at a non-differentiable point)."""
    names: list[str] = []
    fresh: list[SparseGrad] = []
    for g in grads:
        f: SparseGrad = {}
        for k in sorted(g):
            f[k] = em.fresh("g")
            names.append(f[k])
        fresh.append(f)
    return fresh, names


class _Compiler:
    """Expression tree → straight-line statements (scalars: (value, grad); vectors: pairs)."""

    def __init__(self, em: _Emitter, slots: dict[int, int]):
        self.em = em
        self.slots = slots

    def build(self, node: Expr):
        em = self.em
        match node:
            case Const(value):
                return _literal(float(value)), {}, False
            case StateVar(robot, component):
                k = self.slots[robot] + COMPONENT_INDEX[component]
                return em.state(k), {k: _ONE}, False
            case Position(robot):
                kx = self.slots[robot]
                return (em.state(kx), em.state(kx + 1)), ({kx: _ONE}, {kx + 1: _ONE}), True
            case VecLit(x, y):
                vx, gx, _ = self.build(x)
                vy, gy, _ = self.build(y)
                return (vx, vy), (gx, gy), True
            case Neg(arg):
                v, g, is_vec = self.build(arg)
                if is_vec:
                    (vx, vy), (gx, gy) = v, g
                    return ((em.let(f"-{vx}"), em.let(f"-{vy}")),
                            (_lin(em, "-1.0", gx, "0.0", {}), _lin(em, "-1.0", gy, "0.0", {})),
                            True)
                return em.let(f"-{v}"), _lin(em, "-1.0", g, "0.0", {}), False
            case BinOp(op, left, right):
                return self.binop(op, self.build(left), self.build(right))
            case Call(func, args):
                return self.call(func, [self.build(a) for a in args])
        raise TypeError(f"not an STL expression: {node!r}")

    def binop(self, op: str, left, right):
        em = self.em
        lv, lg, lvec = left
        rv, rg, rvec = right
        if op in ("+", "-"):
            sign = "1.0" if op == "+" else "-1.0"
            if lvec:
                (ax, ay), (gax, gay) = lv, lg
                (bx, by), (gbx, gby) = rv, rg
                return ((em.let(f"{ax} + {_times(sign, bx)}"),
                         em.let(f"{ay} + {_times(sign, by)}")),
                        (_lin(em, _ONE, gax, sign, gbx), _lin(em, _ONE, gay, sign, gby)), True)
            return em.let(f"{lv} + {_times(sign, rv)}"), _lin(em, _ONE, lg, sign, rg), False
        if op == "*":
            if not lvec and not rvec:
                return em.let(f"{lv} * {rv}"), _lin(em, rv, lg, lv, rg), False
            (c, gc), (vec, gvec) = ((lv, lg), (rv, rg)) if rvec else ((rv, rg), (lv, lg))
            (vx, vy), (gx, gy) = vec, gvec
            return ((em.let(f"{c} * {vx}"), em.let(f"{c} * {vy}")),
                    (_lin(em, vx, gc, c, gx), _lin(em, vy, gc, c, gy)), True)
        # division by a scalar
        inv = em.let(f"1.0 / {rv}", "inv")
        if lvec:
            (vx, vy), (gx, gy) = lv, lg
            cx = em.let(f"-{vx} * {inv} * {inv}") if rg else "0.0"
            cy = em.let(f"-{vy} * {inv} * {inv}") if rg else "0.0"
            return ((em.let(f"{vx} * {inv}"), em.let(f"{vy} * {inv}")),
                    (_lin(em, inv, gx, cx, rg), _lin(em, inv, gy, cy, rg)), True)
        c = em.let(f"-{lv} * {inv} * {inv}") if rg else "0.0"
        return em.let(f"{lv} * {inv}"), _lin(em, inv, lg, c, rg), False

    def norm(self, arg):
        """|e| of a scalar or ‖v‖ of a vector, gradient 0 at 0 (stl-funnel.md §3)."""
        em = self.em
        v, g, is_vec = arg
        if not is_vec:
            out = em.fresh("n")
            (fresh,), names = _zeroed(em, [g])
            em.lines.append(f"if {v} == 0.0:")
            em.lines.append(f"    {out} = 0.0")
            for name in names:
                em.lines.append(f"    {name} = 0.0")
            em.lines.append("else:")
            sg = em.fresh("sg")
            em.lines.append(f"    {sg} = 1.0 if {v} > 0 else -1.0")
            em.lines.append(f"    {out} = abs({v})")
            for k in fresh:
                em.lines.append(f"    {fresh[k]} = {sg} * {g[k]}")
            return out, fresh, False
        (vx, vy), (gx, gy) = v, g
        length = em.let(f"_hypot({vx}, {vy})", "n")
        union = {k: "" for k in sorted(gx.keys() | gy.keys())}
        (fresh,), names = _zeroed(em, [union])
        em.lines.append(f"if {length} < _TINY:")
        em.lines.append("    " + (" = ".join([*names, "0.0"]) if names else "pass"))
        em.lines.append("else:")
        inv = em.fresh("inv")
        a, b = em.fresh("a"), em.fresh("b")
        em.lines.append(f"    {inv} = 1.0 / {length}")
        em.lines.append(f"    {a} = {vx} * {inv}")
        em.lines.append(f"    {b} = {vy} * {inv}")
        for k in fresh:
            if k in gx and k in gy:
                expr = f"{_times(a, gx[k])} + {_times(b, gy[k])}"
            elif k in gx:
                expr = _times(a, gx[k])
            else:
                expr = _times(b, gy[k])
            em.lines.append(f"    {fresh[k]} = {expr}")
        return length, fresh, False

    def call(self, func: str, args):
        em = self.em
        if func in ("sin", "cos"):
            (v, g, _), = args
            if func == "sin":
                d = em.let(f"_cos({v})", "d") if g else "0.0"
                return em.let(f"_sin({v})"), _lin(em, d, g, "0.0", {}), False
            d = em.let(f"-_sin({v})", "d") if g else "0.0"
            return em.let(f"_cos({v})"), _lin(em, d, g, "0.0", {}), False
        if func in ("abs", "norm"):
            return self.norm(args[0])
        if func == "dist":
            return self.norm(self.binop("-", args[0], args[1]))
        if func == "angdist":
            (a, ga, _), (b, gb, _) = args
            d = em.let(f"_remainder({a} - {b}, _TWO_PI)", "d")
            out = em.fresh("n")
            union = {k: "" for k in sorted(ga.keys() | gb.keys())}
            (fresh,), names = _zeroed(em, [union])
            em.lines.append(f"if {d} == 0.0:")
            em.lines.append("    " + " = ".join([out, *names, "0.0"]))
            em.lines.append("else:")
            sg = em.fresh("sg")
            em.lines.append(f"    {sg} = 1.0 if {d} > 0 else -1.0")
            em.lines.append(f"    {out} = abs({d})")
            for k in fresh:
                if k in ga and k in gb:
                    expr = f"{sg} * {ga[k]} + -{sg} * {gb[k]}"
                elif k in ga:
                    expr = f"{sg} * {ga[k]}"
                else:
                    expr = f"-{sg} * {gb[k]}"
                em.lines.append(f"    {fresh[k]} = {expr}")
            return out, fresh, False
        raise ValueError(f"unknown function {func!r}")


def generate_source(psi: Psi, robots: Sequence[int], eta: float) -> str:
    """Source of ``value_grad(s)`` for ψ over the stacked state of ``robots`` (see module doc)."""
    slots = {robot: 3 * k for k, robot in enumerate(robots)}
    n = 3 * len(robots)
    em = _Emitter()
    comp = _Compiler(em, slots)
    terms: list[tuple[str, SparseGrad]] = []
    for literal in literals(psi):
        pred = literal.pred if isinstance(literal, Not) else literal
        v, g, is_vec = comp.build(predicate_function(pred))
        if is_vec:
            raise TypeError(f"predicate {pred!r} is a vector")
        if isinstance(literal, Not):
            v = em.let(f"-{v}")
            g = {k: em.let(f"-{x}", "g") for k, x in g.items()}
        terms.append((v, g))
    if not terms:
        raise ValueError("ψ has no literal to compile")
    if len(terms) == 1:
        rho, grad = terms[0]
    else:
        # CompiledPsi.value_grad: m, exps, total = sum(exps), weights e/total, accumulation
        m = em.let(f"min({', '.join(v for v, _ in terms)})", "m")
        exps = [em.let(f"_exp({_literal(-eta)} * ({v} - {m}))", "e") for v, _ in terms]
        total = em.let(f"sum(({', '.join(exps)},))", "tot")
        grad = {}
        first = True
        for e, (_, g) in zip(exps, terms, strict=True):
            if not g:
                continue
            w = em.let(f"{e} / {total}", "w")
            if first:
                grad = {k: em.let(f"{w} * {x}", "g") for k, x in g.items()}
                first = False
            else:
                merged = {}
                for k in sorted(grad.keys() | g.keys()):
                    if k in grad and k in g:
                        merged[k] = em.let(f"{grad[k]} + {w} * {g[k]}", "g")
                    elif k in grad:
                        merged[k] = grad[k]
                    else:
                        merged[k] = em.let(f"{w} * {g[k]}", "g")
                grad = merged
        rho = em.let(f"{m} - _log({total}) / {_literal(eta)}", "rho")
    reads = [f"    {name} = s[{k}]" for k, name in sorted(em.state_reads.items())]
    body = ["    " + line for line in em.lines]
    if grad:
        entries = ", ".join(grad.get(k, "0.0") for k in range(n))
        ret = f"    return {rho}, [{entries}]"
    else:
        ret = f"    return {rho}, None"
    return "\n".join(["def value_grad(s):", *reads, *body, ret]) + "\n"


_NAMESPACE = {"_hypot": math.hypot, "_sin": math.sin, "_cos": math.cos, "_exp": math.exp,
              "_log": math.log, "_remainder": math.remainder, "_TWO_PI": 2.0 * math.pi,
              "_TINY": _TINY, "_INF": math.inf, "_NAN": math.nan}


class StraightLinePsi:
    """ψ of one sub-task with a generated ``value_grad`` (module docstring); the generic
    :class:`~tlfleet.agent.stl.robustness.CompiledPsi` is kept as ``reference`` and serves the
    rest."""

    __slots__ = ("eta", "reference", "robots", "source", "value_grad")

    def __init__(self, psi: Psi, robots: Sequence[int], eta: float):
        self.robots = tuple(robots)
        self.eta = eta
        self.reference = CompiledPsi(psi, self.robots, eta)
        self.source = generate_source(psi, self.robots, eta)
        namespace = dict(_NAMESPACE)
        exec(compile(self.source, f"<stl ψ over robots {self.robots}>", "exec"), namespace)
        self.value_grad = namespace["value_grad"]

    def literal_values_grads(self, s: Sequence[float]) -> list[tuple[float, Grad]]:
        return self.reference.literal_values_grads(s)

    def value(self, s: Sequence[float]) -> float:
        return self.reference.value(s)

    def value_min(self, s: Sequence[float]) -> float:
        return self.reference.value_min(s)
