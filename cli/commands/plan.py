"""``tlfleet plan SCENARIO [--robot ID] [--json]``: optimal prefix–suffix plan of each LTL robot.

For every LTL robot (or only ``--robot ID``) prints the Büchi and product sizes, the plan (prefix
once, then the suffix forever, as region names), its cost ``prefix + β·suffix`` and the time each
step of paper Algorithm 1 took (ltl-planning.md §5). Unsatisfiable tasks are reported as errors.

Edge weights (ltl-planning.md §3) are by default what the robot's agent plans with (``--weights
map``): the length of a path around the obstacles that enters no region but the transition's two
(docs/ltl-navigation.md §2), equal to the straight line where that is free, and no edge where
there is none; ``--weights euclidean`` takes the straight-line distances between region centres.
A task with no plan under the keep-out rule is reported in one line naming the region in the
way.
"""

from __future__ import annotations

import argparse
import json
import sys

from tlfleet.agent.ltl.planner import Plan, plan_robot
from tlfleet.agent.policy.ltl import plan_on_map
from tlfleet.agent.scenario import load_scenario
from tlfleet.cli.arg_types import scenario_file

NAME = "plan"
HELP = "compute the optimal prefix–suffix plan of each LTL robot"
EXAMPLES = (
    ("tlfleet plan scenario1.toml", "the optimal prefix-suffix plan of every LTL robot"),
    ("tlfleet plan scenario1.toml --robot 1 --json", "robot 1's plan as JSON"),
)
EXIT_CODES = {0: "every plan was found",
              1: "an invalid scenario, or an LTL task no run of the map satisfies"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=scenario_file,
                        help="scenario TOML file or a bundled scenario's name")
    parser.add_argument("--robot", type=int, default=None, help="only this robot id")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    parser.add_argument("--weights", choices=("map", "euclidean"), default="map",
                        help="transition weights: the agent's keep-out path lengths around "
                             "obstacles (default) or straight-line distances")


def _ms(seconds: float) -> str:
    return f"{1e3 * seconds:.2f} ms"


def format_plan(p: Plan) -> str:
    """Human-readable block for one robot's plan."""
    t = p.timings
    return "\n".join([
        f"robot {p.robot}: {p.formula}",
        f"  Büchi: {p.buchi_states} states, {p.buchi_edges} edges; "
        f"product: {p.product_states} states, {p.product_edges} edges",
        f"  prefix: {' -> '.join(p.prefix) if p.prefix else '(empty)'}",
        f"  suffix: ({' -> '.join(p.suffix)})^ω",
        f"  cost: {p.cost:.3f} = {p.prefix_cost:.3f} + {p.beta:g} × {p.suffix_cost:.3f}",
        f"  time: parse {_ms(t.parse)}, translate {_ms(t.translate)}, "
        f"product {_ms(t.product)}, search {_ms(t.search)}, total {_ms(t.total)}",
    ])


def run(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario)
    if args.robot is not None:
        if args.robot not in scenario.robot_ids:
            known = ", ".join(str(i) for i in scenario.robot_ids)
            print(f"tlfleet plan: scenario {scenario.name!r} has no robot {args.robot} "
                  f"(robots: {known})", file=sys.stderr)
            return 1
        robot = scenario.robot(args.robot)
        if robot.ltl is None:
            print(f"tlfleet plan: robot {args.robot} has no LTL task", file=sys.stderr)
            return 1
        robots = [robot]
    else:
        robots = [r for r in sorted(scenario.robots, key=lambda r: r.id) if r.ltl is not None]
    plans = []
    for robot in robots:
        plans.append(plan_on_map(scenario, robot.id) if args.weights == "map"
                     else plan_robot(scenario, robot.id))
    if args.json:
        print(json.dumps({"scenario": scenario.name, "plans": [p.to_dict() for p in plans]},
                         indent=2))
    else:
        if not plans:
            print(f"scenario {scenario.name}: no LTL robot")
        for p in plans:
            print(format_plan(p))
    return 0
