"""``tlfleet agent SCENARIO --robot ID``: the agent process of one robot (architecture.md §1).

Dispatches on the robot's task: an LTL robot runs ``agent.runtime.ltl_agent`` (plan, then
navigation at ``scenario.ltl.control_rate``), an STL robot ``agent.runtime.stl_agent`` (funnel
control at ``scenario.stl.control_rate`` with stage-2 collaboration). Exit codes: 0 after a clean
stop (``Control(stop)``, SIGINT, SIGTERM), 1 on a fault (e.g. an unsatisfiable LTL task, reported
as ``Event(kind="fault")`` first).
"""

from __future__ import annotations

import argparse

from agent.runtime.transport import add_transport_arguments
from agent.scenario import load_scenario

NAME = "agent"
HELP = "run the agent process of one robot"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario TOML file")
    parser.add_argument("--robot", type=int, required=True, metavar="ID", help="robot id")
    parser.add_argument("--stale-after", type=float, default=0.5, metavar="S",
                        help="no mocap frame for S seconds (wall) → zero command (default 0.5)")
    parser.add_argument("--collab-timeout", type=float, default=0.25, metavar="S",
                        help="wait at most S seconds (wall) for a partner's collab reply "
                             "(STL robots; default 0.25)")
    add_transport_arguments(parser)


def run(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario)
    if args.robot not in scenario.robot_ids:
        known = ", ".join(str(r) for r in scenario.robot_ids)
        raise SystemExit(f"tlfleet agent: scenario {scenario.name!r} has no robot {args.robot} "
                         f"(robots: {known})")
    robot = scenario.robot(args.robot)
    for flag, value in (("--stale-after", args.stale_after),
                        ("--collab-timeout", args.collab_timeout)):
        if value <= 0:
            raise SystemExit(f"tlfleet agent: {flag} must be positive, got {value}")
    if robot.is_ltl:
        from agent.runtime import ltl_agent

        return ltl_agent.main(args, scenario)
    from agent.runtime import stl_agent

    return stl_agent.main(args, scenario)
