"""Everything an agent process builds before its liveliness token, built once beforehand.

``tlfleet check`` and ``tlfleet run`` call :func:`check_launch` after loading the scenario, so a
file ``check`` calls valid is one whose every agent starts, and a run refuses (exit 1, nothing
launched) exactly the files ``check`` rejects. For each robot it builds what that robot's agent
process builds, with the same code and the same arguments
(:func:`tlfleet.agent.runtime.stl_agent.main`, :func:`tlfleet.agent.runtime.ltl_agent.main`):

* an STL robot: its agent (:func:`tlfleet.agent.policy.stl.build_agents` with ``robots=[id]``):
  every sub-task compiled, ρ_opt resolved (an unbounded predicate needs ``rho_opt``), the phase
  start times checked;
* an LTL robot: its agent (:class:`tlfleet.agent.policy.ltl.LtlAgent`: the automaton, the
  transition system over the regions with the map's path lengths, the navigation stack, the
  coupling limits of the STL tasks that name it) and its first plan (paper Algorithm 1): a task
  no run of the transition system satisfies (the robot starts inside the region ``G !c``
  forbids, a region walled in by obstacles, ``G a & G b`` with disjoint regions) is refused here.

STL robots come first, so that an STL task an LTL robot's coupling limits would build is
reported at the STL robot's own field. Every failure is a
:class:`~tlfleet.bus.errors.ScenarioError` naming the file, the robot's field and the reason.
"""

from __future__ import annotations

from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.scenario.fields import robot_field
from tlfleet.bus.errors import ScenarioError, TlfleetError


def check_launch(scenario: Scenario, source: str | None = None) -> None:
    """Build every agent of ``scenario`` as its process would (module docstring); the first
    failure as a :class:`ScenarioError`."""
    from tlfleet.agent.policy.ltl import LtlAgent
    from tlfleet.agent.policy.stl import build_agents

    where = source or (str(scenario.source) if scenario.source else "<scenario>")
    ordered = sorted(enumerate(scenario.robots), key=lambda item: (item[1].is_ltl, item[1].id))
    for index, robot in ordered:
        field = robot_field(index, robot.id)
        try:
            if robot.is_stl:
                build_agents(scenario, robots=[robot.id], warn=False)
            else:
                LtlAgent(scenario, robot.id).plan()
        except TlfleetError as exc:
            raise ScenarioError(where, f"{field}.{'stl' if robot.is_stl else 'ltl'}",
                                f"robot {robot.id}'s agent cannot start: {exc}") from None
        except ValueError as exc:  # a model check of a core (a limit, a window…)
            raise ScenarioError(where, field,
                                f"robot {robot.id}'s agent cannot start: {exc}") from None
