"""Robust semantics of ψ (paper §II-B; stl-funnel.md §3): smooth n-ary conjunction and its gradient.

    ρ^μ = h,   ρ^¬μ = −h,   ρ^{ψ1 ∧ … ∧ ψn} = −(1/η)·ln Σ_k exp(−η ρ_k)        (LSE, η = 10)

evaluated stably as ρ = m − (1/η)·ln Σ_k exp(−η(ρ_k − m)) with m = min_k ρ_k, with gradient
∂ρ/∂x = Σ_k w_k ∂ρ_k/∂x, w_k = exp(−η(ρ_k − m)) / Σ_l exp(−η(ρ_l − m)) (soft-min weights).
Bounds: min_k ρ_k − ln(n)/η ≤ ρ ≤ min_k ρ_k. The standard semantics uses min instead.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from tlfleet.agent.stl.evaluate import Grad, compile_expr, evaluate_array
from tlfleet.agent.stl.syntax import Not, Predicate, Psi, literals, predicate_function, robots_of


def smooth_and(values: Sequence[float], eta: float) -> float:
    """Stable LSE under-approximation of min(values) (stl-funnel.md §3); +∞ for no values."""
    if not values:
        return math.inf
    m = min(values)
    if len(values) == 1 or math.isinf(m):
        return m
    total = 0.0
    for v in values:
        total += math.exp(-eta * (v - m))
    return m - math.log(total) / eta


def smooth_and_weights(values: Sequence[float], eta: float) -> list[float]:
    """Soft-min weights w_k (they sum to 1)."""
    m = min(values)
    exps = [math.exp(-eta * (v - m)) for v in values]
    total = sum(exps)
    return [e / total for e in exps]


def smooth_and_grad(values: Sequence[float], grads: Sequence[Sequence[float]],
                    eta: float) -> tuple[float, np.ndarray]:
    """(ρ, Σ_k w_k ∇ρ_k) for the LSE conjunction; ``grads[k]`` is ∇ρ_k (any common length)."""
    weights = smooth_and_weights(values, eta)
    grad = np.zeros(len(grads[0]))
    for w, g in zip(weights, grads, strict=True):
        grad += w * np.asarray(g, dtype=float)
    return smooth_and(values, eta), grad


def smooth_and_array(values: Sequence[np.ndarray], eta: float) -> np.ndarray:
    """Row-wise stable LSE of (N,) arrays (vectorised monitors)."""
    stacked = np.vstack([np.broadcast_to(np.asarray(v, dtype=float), np.shape(values[0]))
                         for v in values])
    m = stacked.min(axis=0)
    return m - np.log(np.exp(-eta * (stacked - m)).sum(axis=0)) / eta


class CompiledPsi:
    """ψ compiled for the control step over the stacked state of ``robots`` (stl-funnel.md §6.1).

    ``value_grad(s)`` returns the smooth ρ^ψ and its full gradient ∂ρ/∂s (list, length 3P, or
    ``None`` if zero); ``value(s)`` the smooth value only; ``value_min(s)`` the standard (min) one.
    Not a dataclass on purpose: it holds closures, and is built once per sub-task.
    """

    __slots__ = ("_fns", "eta", "robots")

    def __init__(self, psi: Psi, robots: Sequence[int], eta: float):
        self.robots = tuple(robots)
        self.eta = eta
        fns: list[tuple[Callable, float]] = []
        for literal in literals(psi):
            pred = literal.pred if isinstance(literal, Not) else literal
            fns.append((compile_expr(predicate_function(pred), self.robots),
                        -1.0 if isinstance(literal, Not) else 1.0))
        self._fns = tuple(fns)

    def literal_values_grads(self, s: Sequence[float]) -> list[tuple[float, Grad]]:
        out = []
        for fn, sign in self._fns:
            v, g = fn(s)
            if sign < 0:
                v = -v
                g = None if g is None else [-x for x in g]
            out.append((v, g))
        return out

    def value_grad(self, s: Sequence[float]) -> tuple[float, Grad]:
        fns = self._fns
        if len(fns) == 1:
            fn, sign = fns[0]
            v, g = fn(s)
            if sign > 0:
                return v, g
            return -v, None if g is None else [-x for x in g]
        pairs = self.literal_values_grads(s)
        eta = self.eta
        m = min(v for v, _ in pairs)
        exps = [math.exp(-eta * (v - m)) for v, _ in pairs]
        total = sum(exps)
        grad: Grad = None
        for e, (_, g) in zip(exps, pairs, strict=True):
            if g is None:
                continue
            w = e / total
            grad = [w * x for x in g] if grad is None else [a + w * x for a, x in zip(grad, g,
                                                                                         strict=True)]
        return m - math.log(total) / eta, grad

    def value(self, s: Sequence[float]) -> float:
        if not self._fns:
            return math.inf
        return smooth_and([sign * fn(s)[0] for fn, sign in self._fns], self.eta)

    def value_min(self, s: Sequence[float]) -> float:
        if not self._fns:
            return math.inf
        return min(sign * fn(s)[0] for fn, sign in self._fns)


def psi_array(psi: Psi, states: Mapping[int, np.ndarray], smooth: bool = False,
              eta: float = 10.0) -> np.ndarray:
    """ρ^ψ at every sample (``states[j]``: (N, 3)) as an (N,) array; standard (min) or smooth."""
    n = len(next(iter(states.values()))) if states else 0
    values = []
    for literal in literals(psi):
        pred: Predicate = literal.pred if isinstance(literal, Not) else literal
        h = np.broadcast_to(np.asarray(evaluate_array(predicate_function(pred), states),
                                       dtype=float), (n,))
        values.append(-h if isinstance(literal, Not) else h)
    if not values:
        return np.full(n, math.inf)
    if len(values) == 1:
        return np.array(values[0], dtype=float)
    if smooth:
        return smooth_and_array(values, eta)
    return np.minimum.reduce(values)


def participants(psi: Psi) -> tuple[int, ...]:
    """Robots whose states enter ψ, ascending."""
    return tuple(sorted(robots_of(psi)))
