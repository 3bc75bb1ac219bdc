"""``tlfleet agent SCENARIO --robot ID``: the agent process of one robot (architecture.md §1).

A thin wrapper: the flags become an :class:`~tlfleet.agent.runtime.config.AgentConfig` and
:func:`tlfleet.agent.runtime.main.main` runs the robot's LTL or STL agent. Exit codes: 0 after a
clean stop (``Control(stop)``, SIGINT, SIGTERM), 1 on a fault (e.g. an unsatisfiable LTL task,
reported as ``Event(kind="fault")`` first).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from tlfleet.agent.runtime.config import AgentConfig, AgentConfigError
from tlfleet.cli.arg_types import scenario_file
from tlfleet.cli.process_flags import (
    add_orphan_argument,
    add_process_arguments,
    apply_process_flags,
)
from tlfleet.cli.transport_flags import add_transport_arguments, transport_config

NAME = "agent"
HELP = "run the agent process of one robot"
# a process's log says what it is doing (waiting for start, listening, ...) without -v;
# -q leaves the warnings only (tlfleet.cli.conventions.log_level)
DEFAULT_LOG_LEVEL = logging.INFO
EXAMPLES = (
    ("tlfleet agent scenario1.toml --robot 2 --connect tcp/127.0.0.1:7447",
     "robot 2 of Scenario 1 joins the fleet whose router listens on port 7447"),
)
EXIT_CODES = {0: "a clean stop (Control(stop), SIGINT or SIGTERM)",
              1: "a fault (an invalid scenario, an unsatisfiable LTL task, ...), reported as a "
                 "fault event first"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=scenario_file,
                        help="scenario TOML file or a bundled scenario's name")
    parser.add_argument("--robot", type=int, required=True, metavar="ID", help="robot id")
    parser.add_argument("--stale-after", type=float, default=0.5, metavar="S",
                        help="no mocap frame for S seconds (wall) → zero command (default 0.5)")
    parser.add_argument("--collab-timeout", type=float, default=0.25, metavar="S",
                        help="wait at most S seconds (wall) for a partner's collab reply "
                             "(STL robots; default 0.25)")
    parser.add_argument("--heartbeat", action="store_true",
                        help="an agent that reads only every d-th frame (an LTL robot) also "
                             "watches the simulator's clock key, so it notices a lost simulator "
                             "within --stale-after instead of --stale-after plus two frame gaps; "
                             "costs one tiny message per tick (tlfleet run turns it on for runs "
                             "with link faults)")
    add_transport_arguments(parser)
    add_process_arguments(parser)
    add_orphan_argument(parser)


def config_from_args(args: argparse.Namespace) -> AgentConfig:
    try:
        return AgentConfig(robot=args.robot, scenario=Path(args.scenario),
                           stale_after=args.stale_after, collab_timeout=args.collab_timeout,
                           heartbeat=args.heartbeat, orphan_after=args.orphan_after,
                           transport=transport_config(args, f"robot{args.robot}"))
    except AgentConfigError as exc:
        raise SystemExit(f"tlfleet agent: {exc}") from None


def run(args: argparse.Namespace) -> int:
    from tlfleet.agent.runtime.main import main

    config = config_from_args(args)
    apply_process_flags(args, f"agent/{args.robot}")
    try:
        return main(config)
    except AgentConfigError as exc:  # raised before any session is opened
        raise SystemExit(f"tlfleet agent: {exc}") from None
