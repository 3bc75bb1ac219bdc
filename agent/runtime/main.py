"""``tlfleet agent``'s entry point: one robot's process, dispatched on its task."""

from __future__ import annotations

from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.runtime.config import AgentConfig, AgentConfigError
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.errors import TlfleetError


def main(config: AgentConfig, scenario: Scenario | None = None) -> int:
    """``tlfleet agent``: the process of ``config.robot``, dispatched on its task — an LTL robot
    runs :mod:`tlfleet.agent.runtime.ltl_agent` (plan, then navigation), an STL robot
    :mod:`tlfleet.agent.runtime.stl_agent` (funnel control with stage-2 collaboration). Exit codes:
    0 after a clean stop (``Control(stop)``, SIGINT, SIGTERM), 1 on a fault."""
    if scenario is None:
        if config.scenario is None:
            raise TlfleetError("agent: no scenario given")
        scenario = load_scenario(config.scenario)
    if config.robot not in scenario.robot_ids:
        known = ", ".join(str(r) for r in scenario.robot_ids)
        raise AgentConfigError(f"scenario {scenario.name!r} has no robot {config.robot} "
                               f"(robots: {known})")
    if scenario.robot(config.robot).is_ltl:
        from tlfleet.agent.runtime import ltl_agent

        return ltl_agent.main(config, scenario)
    from tlfleet.agent.runtime import stl_agent

    return stl_agent.main(config, scenario)
