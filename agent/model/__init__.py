"""The scenario model: the typed, immutable data every layer above shares (docs/architecture.md §5).

Arena, obstacles, regions, robots (pose, radius, limits, task texts), the planners' and the
simulator's parameters, and the fault specifications. Lengths in metres, angles in radians, times
in seconds, rates in Hz. Pure data: it imports nothing of the project but the error hierarchy; the
cores build on it, and ``tlfleet.agent.scenario`` is the only code that reads it from a file.
"""

from tlfleet.agent.model.scenario import (
    Arena,
    DiscObstacle,
    LtlParams,
    NavParams,
    OmniLimits,
    RectObstacle,
    Region,
    Robot,
    RobotKind,
    Scenario,
    SimParams,
    StlParams,
    UnicycleLimits,
)

__all__ = [
    "Arena",
    "DiscObstacle",
    "LtlParams",
    "NavParams",
    "OmniLimits",
    "RectObstacle",
    "Region",
    "Robot",
    "RobotKind",
    "Scenario",
    "SimParams",
    "StlParams",
    "UnicycleLimits",
]
