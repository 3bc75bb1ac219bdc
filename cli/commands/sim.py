"""``tlfleet sim SCENARIO``: run the pymunk simulator process of a scenario (architecture.md §1).

The process publishes the clock, mocap frames and events, reads the agents' commands and runs
until sim time reaches ``--duration``, ``Control(stop)``, SIGINT or SIGTERM
(``tlfleet.sim.process``).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from tlfleet.cli.arg_types import non_negative_float, positive_float, scenario_file
from tlfleet.cli.process_flags import (
    add_orphan_argument,
    add_process_arguments,
    apply_process_flags,
)
from tlfleet.cli.transport_flags import add_transport_arguments, transport_config

NAME = "sim"
HELP = "run the pymunk simulator process of a scenario"
# a process's log says what it is doing (waiting for start, listening, ...) without -v;
# -q leaves the warnings only (tlfleet.cli.conventions.log_level)
DEFAULT_LOG_LEVEL = logging.INFO
EXAMPLES = (
    ("tlfleet sim scenario1.toml --lockstep --connect tcp/127.0.0.1:7447",
     "simulate Scenario 1 in lockstep for a fleet whose router listens on port 7447"),
    ("tlfleet sim scenario2.toml --realtime --duration 20 --connect tcp/127.0.0.1:7447",
     "20 s of Scenario 2 on wall-clock time"),
)
EXIT_CODES = {0: "the run ended (its duration, Control(stop), SIGINT or SIGTERM)",
              1: "an invalid scenario or no router at --connect"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=scenario_file,
                        help="scenario TOML file or a bundled scenario's name")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--lockstep", dest="realtime", action="store_false",
                      help="wait for every due agent's command each tick (default; deterministic)")
    mode.add_argument("--realtime", dest="realtime", action="store_true",
                      help="step the physics on wall-clock time")
    parser.set_defaults(realtime=False)
    parser.add_argument("--seed", type=int, default=None,
                        help="seed of the disturbance and mocap noise (default: the scenario's)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="sim time to run [s] (default: the scenario's duration)")
    parser.add_argument("--tick-timeout", type=float, default=2.0, metavar="S",
                        help="lockstep: wall time to wait for the due commands of a tick "
                             "(default 2 s)")
    parser.add_argument("--max-command-age", type=float, default=None, metavar="S",
                        help="realtime: ignore commands answering frames older than this [s sim "
                             "time] (default: 5 control periods of the robot)")
    parser.add_argument("--max-speed", type=positive_float, default=None, metavar="FACTOR",
                        help="lockstep: let sim time run at most FACTOR × wall-clock time, e.g. 1 "
                             "to watch a run live (default: as fast as the agents answer; the "
                             "trajectory is the same either way)")
    parser.add_argument("--backfill-seconds", type=non_negative_float, default=None,
                        metavar="S",
                        help="sim time of recent frames kept to backfill a recorder that missed "
                             "them during a link cut [s] (default 10; also bounded to 8 MiB)")
    add_transport_arguments(parser)
    add_process_arguments(parser)
    add_orphan_argument(parser)


def process_config(args: argparse.Namespace):  # -> tlfleet.sim.process.SimProcessConfig
    from tlfleet.sim.process import SimProcessConfig

    return SimProcessConfig(scenario=Path(args.scenario),
                            mode="realtime" if args.realtime else "lockstep",
                            duration=args.duration, seed=args.seed,
                            tick_timeout=args.tick_timeout,
                            transport=transport_config(args, "sim"),
                            max_command_age=args.max_command_age,
                            max_speed=args.max_speed, orphan_after=args.orphan_after,
                            **_backfill(args))


def _backfill(args: argparse.Namespace) -> dict:
    return {} if args.backfill_seconds is None else {"backfill_seconds": args.backfill_seconds}


def sim_config(args: argparse.Namespace, scenario):  # -> tlfleet.sim.process.SimConfig
    """The :class:`~tlfleet.sim.process.SimConfig` these flags give for a loaded scenario."""
    from tlfleet.sim.process import SimConfig

    return SimConfig.for_scenario(scenario, mode="realtime" if args.realtime else "lockstep",
                                  duration=args.duration, seed=args.seed,
                                  tick_timeout=args.tick_timeout,
                                  max_command_age=args.max_command_age,
                                  max_speed=args.max_speed, **_backfill(args))


def run(args: argparse.Namespace) -> int:
    from tlfleet.sim.process import main

    config = process_config(args)
    apply_process_flags(args, "sim")
    return main(config)
