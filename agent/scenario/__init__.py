"""Scenario files: the typed model (``model``) and the validating TOML loader (``loader``).

Pure code (stdlib + the formula parsers); usable by the agents, the simulator and the coordinator
without any of them importing the coordinator.
"""

from agent.scenario.loader import load_scenario, parse_scenario
from agent.scenario.model import (
    Arena,
    DiscObstacle,
    LtlParams,
    OmniLimits,
    RectObstacle,
    Region,
    Robot,
    Scenario,
    SimParams,
    StlParams,
    UnicycleLimits,
)

__all__ = [
    "Arena",
    "DiscObstacle",
    "LtlParams",
    "OmniLimits",
    "RectObstacle",
    "Region",
    "Robot",
    "Scenario",
    "SimParams",
    "StlParams",
    "UnicycleLimits",
    "load_scenario",
    "parse_scenario",
]
