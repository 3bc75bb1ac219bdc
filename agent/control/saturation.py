"""Velocity saturation of an omnidirectional robot (stl-funnel.md §6.1 step 4, §6.2; paper §III-B).

u = (v_x, v_y, ω) in the world frame ([m/s], [m/s], [rad/s]). [OUR CHOICE] separate limits, as the
authors' code does: the planar part is scaled to ‖(v_x, v_y)‖ ≤ u_max,lin (direction kept,
the paper's "u_max·u/‖u‖") and ω is clipped to |ω| ≤ u_max,ang. The paper's single norm over
all three entries would mix units.
"""

from __future__ import annotations

import math


def saturate(u: tuple[float, float, float], umax_lin: float,
             umax_ang: float) -> tuple[float, float, float]:
    """Saturated (v_x, v_y, ω): planar part scaled onto the disc of radius ``umax_lin`` [m/s],
    ω clipped to [−``umax_ang``, ``umax_ang``] [rad/s]."""
    vx, vy, w = u
    speed = math.hypot(vx, vy)
    if speed > umax_lin:
        k = umax_lin / speed
        vx *= k
        vy *= k
    if w > umax_ang:
        w = umax_ang
    elif w < -umax_ang:
        w = -umax_ang
    return vx, vy, w
