"""How fast a robot at its speed limit raises ρ^ψ: the minimal-time bound (stl-saturation.md §1).

An omnidirectional robot i moves its position z_i at ‖ż_i‖ ≤ u_lin [m/s] and its heading θ_i at
|θ̇_i| ≤ u_ang [rad/s] (paper §III-B, saturation ū_nom). Robot i alone raises a conjunct ρ_k of ψ
(a predicate's h, or −h for ¬μ) at most at the rate

    c_k = u_lin·‖∂ρ_k/∂z_i‖ + u_ang·|∂ρ_k/∂θ_i|                                   [1/s]

and for the fragment's shapes this rate holds all the way along a straight path (c − ‖z_i − p‖,
half-planes a·z_i ≥ c and angle predicates have gradients of constant norm), so conjunct k needs at
least T_k = (level − ρ_k)⁺/c_k to reach ``level``, and ψ needs T = max_k T_k: the **minimal-time
bound** (a lower bound: conjuncts that pull apart need longer). Conjuncts that robot i cannot move
(c_k = 0: they depend on other robots only) are left out.

The smooth conjunction ρ^ψ ≥ min_k ρ_k − ln(n)/η (stl-funnel.md §3), so a funnel on ρ^ψ that
should reach ``level`` aims each conjunct at level + ln(n)/η (``smooth`` below). The average rate
(level − ρ^ψ(x̄_0))/T is then one the robot can keep up with: the best-case curve min_k(ρ_k + c_k·t)
is concave in t, so the chord from its start to its end lies under it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from tlfleet.agent.stl.task import Task


def conjunct_rates(task: Task, state: Sequence[float], robot: int, max_lin: float,
                   max_ang: float) -> tuple[tuple[float, float], ...]:
    """(ρ_k, c_k) of every conjunct of ``task`` at the stacked state ``state`` for robot
    ``robot`` with limits ``max_lin`` [m/s] and ``max_ang`` [rad/s] (module docstring)."""
    b0 = task.block(robot)
    out = []
    for value, grad in task.compiled.literal_values_grads(state):
        if grad is None:
            rate = 0.0
        else:
            gx, gy, gth = grad[b0], grad[b0 + 1], grad[b0 + 2]
            rate = max_lin * math.hypot(gx, gy) + max_ang * abs(gth)
        out.append((float(value), rate if math.isfinite(rate) else 0.0))
    return tuple(out)


def minimal_time(rates: Sequence[tuple[float, float]], level: float = 0.0, *,
                 smooth: float = 0.0) -> float:
    """T = max_k (level + smooth − ρ_k)⁺/c_k [s] over the conjuncts robot i can move (c_k > 0)
    of ``rates`` (:func:`conjunct_rates`); 0 when each of them is at the level already."""
    worst = 0.0
    for value, rate in rates:
        need = level + smooth - value
        if need > 0.0 and rate > 0.0:
            worst = max(worst, need / rate)
    return worst


def smoothing_offset(n: int, eta: float) -> float:
    """ln(n)/η: how far the smooth conjunction of n conjuncts may lie below their min (§3)."""
    return math.log(n) / eta if n > 1 else 0.0


def design_rate(task: Task, state: Sequence[float], robot: int, rho: float, level: float,
                max_lin: float, max_ang: float, at_least: float = 0.0) -> float:
    """The rate v [1/s] at which robot ``robot`` can raise ρ^ψ (= ``rho`` now) towards ``level``:
    (level − ρ)/T with T the minimal-time bound of the conjuncts aimed at level + ln(n)/η, or
    ``at_least`` [s] if that is longer (e.g. the distance to the set where the conjuncts all
    hold at once, which the bound of separate conjuncts does not see); the gradient rate
    u_lin·‖∂ρ/∂z_i‖ + u_ang·|∂ρ/∂θ_i| of the smooth ρ^ψ when ρ is at the level already (or no
    conjunct needs time); 0 when robot i cannot move ρ^ψ at all."""
    rates = conjunct_rates(task, state, robot, max_lin, max_ang)
    if level > rho:
        t = max(minimal_time(rates, level, smooth=smoothing_offset(len(rates), task.eta)),
                at_least)
        if t > 0.0:
            return (level - rho) / t
    _, grad = task.compiled.value_grad(state)
    if grad is None:
        return 0.0
    b0 = task.block(robot)
    rate = max_lin * math.hypot(grad[b0], grad[b0 + 1]) + max_ang * abs(grad[b0 + 2])
    return rate if math.isfinite(rate) else 0.0
