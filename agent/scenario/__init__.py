"""Scenario files: TOML in, a checked :class:`~tlfleet.agent.model.Scenario` out.

``loader`` reads and validates a file (file, field path and reason on every error), ``validation``
checks sizes, rates, geometry and task satisfiability, ``stl_checks`` the STL sub-tasks' windows
and suprema. It sits above the cores because checking a task means parsing and translating it.
"""

from tlfleet.agent.scenario.loader import load_scenario, parse_scenario

__all__ = ["load_scenario", "parse_scenario"]
