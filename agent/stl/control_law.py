"""Nominal funnel control law: paper eq. (5) plus gradient normalisation (stl-funnel.md §6.1)::

    u_nom,i = −k_ε·ε(x̄_i, t)·∇,     ∇ = ∂ρ^ψ/∂x_i / ‖∂ρ^ψ/∂x_i‖   (normalize_grad, default)
                                     ∇ = ∂ρ^ψ/∂x_i                   (eq. (5) literally)

x_i = (x [m], y [m], θ [rad]); u = (v_x [m/s], v_y [m/s], ω [rad/s]) in the world frame, before
saturation. A zero or non-finite gradient gives u = 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal


@dataclass(frozen=True)
class ControlParams:
    """Nominal-law options and the saturation limits (stl-funnel.md §6.1, §15)."""

    max_lin: float = 0.2  # [m/s] bound on ‖(v_x, v_y)‖
    max_ang: float = 6.28  # [rad/s] bound on |ω|
    normalize_grad: bool = True  # §6.1 step 1 [OUR CHOICE, code behaviour]
    k_eps: float = 1.0  # §6.1 step 2 [AUTHORS' CODE: no gain]
    hold_F_when_above_r: bool = False  # §6.1 step 5, the authors' code (docs/stl-saturation.md §6)
    saturation: Literal["separate", "norm"] = "separate"  # §6.1 step 4 [OUR CHOICE]; "norm" is
    # the paper's single norm over (v_x, v_y, ω) with u_max = max_lin


def nominal_velocity(eps: float, grad_i: Sequence[float] | None, normalize: bool = True,
                     k_eps: float = 1.0) -> tuple[float, float, float]:
    """u_nom = −k_ε·ε·∇ for the agent's own 3-gradient ``grad_i`` (``None`` = zero)."""
    if grad_i is None:
        return 0.0, 0.0, 0.0
    gx, gy, gth = grad_i
    scale = -k_eps * eps
    if normalize:
        length = math.sqrt(gx * gx + gy * gy + gth * gth)
        if length == 0.0 or not math.isfinite(length):
            return 0.0, 0.0, 0.0
        scale /= length
    u = (scale * gx, scale * gy, scale * gth)
    if not all(math.isfinite(v) for v in u):
        return 0.0, 0.0, 0.0
    return u
