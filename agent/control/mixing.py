"""Mixed saturated control law, paper eq. (6) (stl-funnel.md §6.2)::

    u_mix,i = β_i·ū_col,i + ū_nom,i,        ū_mix,i = saturate(u_mix,i)

with the separate linear/angular saturation of ``tlfleet.agent.control.saturation``. Velocities in
m/s and rad/s, world frame.
"""

from __future__ import annotations

from typing import Literal

from tlfleet.agent.control.saturation import saturate


def mix(u_nom_bar: tuple[float, float, float], u_col_bar: tuple[float, float, float], beta: float,
        max_lin: float, max_ang: float,
        mode: Literal["separate", "norm"] = "separate") -> tuple[float, float, float]:
    """ū_mix = saturate(β·ū_col + ū_nom) (eq. (6)); ``mode`` as in ``saturate``."""
    return saturate((beta * u_col_bar[0] + u_nom_bar[0], beta * u_col_bar[1] + u_nom_bar[1],
                     beta * u_col_bar[2] + u_nom_bar[2]), max_lin, max_ang, mode)
