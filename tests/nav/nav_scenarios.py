"""The paper's LTL robots alone on an empty arena (scenarios.md), for the navigation tests."""

from __future__ import annotations

import math

from tlfleet.agent.model.scenario import Arena, Region, Robot, Scenario


def scenario1() -> Scenario:
    """Scenario 1's LTL robot 1 alone (scenarios.md); the other robots are not LTL robots."""
    regions = (Region("a11", (-2.0, -2.5)), Region("a12", (-2.0, 2.5)))
    robot = Robot(1, "unicycle", (-2.0, -2.5, math.pi / 2), ltl="G F a11 & G F a12")
    return Scenario("scenario1", "f", 90.0, Arena(), regions, (robot,))


def scenario3() -> Scenario:
    """Scenario 3's LTL robot 1 with its five regions."""
    regions = (
        Region("a1", (-1.5, -1.5)),
        Region("a2", (1.5, -1.5)),
        Region("a3", (1.5, 1.5)),
        Region("a4", (-1.5, 1.5)),
        Region("a5", (0.0, 0.0)),
    )
    robot = Robot(1, "unicycle", (-2.0, -2.0, 0.0), ltl="F a1 & F a2 & F a3 & F a4 & F a5")
    return Scenario("scenario3", "f", 100.0, Arena(), regions, (robot,))
