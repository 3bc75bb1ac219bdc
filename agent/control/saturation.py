"""Velocity saturation of an omnidirectional robot (stl-funnel.md §6.1 step 4, §6.2; paper §III-B).

u = (v_x, v_y, ω) in the world frame ([m/s], [m/s], [rad/s]). [OUR CHOICE] separate limits, as the
authors' code does: the planar part is scaled to ‖(v_x, v_y)‖ ≤ u_max,lin (direction kept,
the paper's "u_max·u/‖u‖") and ω is clipped to |ω| ≤ u_max,ang. The paper's single norm over
all three entries would mix units.
"""

from __future__ import annotations

import math
from typing import Literal


def saturate(u: tuple[float, float, float], max_lin: float, max_ang: float,
             mode: Literal["separate", "norm"] = "separate") -> tuple[float, float, float]:
    """Saturated (v_x, v_y, ω).

    ``separate`` (default): planar part scaled onto the disc of radius ``max_lin`` [m/s], ω
    clipped to [−``max_ang``, ``max_ang``] [rad/s]. ``norm``: the paper's literal form,
    u := u_max·u/‖u‖ over all three entries with u_max = ``max_lin``.
    """
    vx, vy, w = u
    if mode == "norm":
        length = math.sqrt(vx * vx + vy * vy + w * w)
        if length > max_lin:
            k = max_lin / length
            return vx * k, vy * k, w * k
        return vx, vy, w
    speed = math.hypot(vx, vy)
    if speed > max_lin:
        k = max_lin / speed
        vx *= k
        vy *= k
    if w > max_ang:
        w = max_ang
    elif w < -max_ang:
        w = -max_ang
    return vx, vy, w
