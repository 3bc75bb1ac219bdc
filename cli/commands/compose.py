"""``tlfleet compose SCENARIO [--out DIR|FILE.yaml] [--lockstep|--realtime] [--insecure]``: write
the docker compose file of a scenario's fleet (:mod:`coordinator.compose`), secured by default
(mutual TLS, the router's access control; keys from ``${TLFLEET_KEYS}``). An invalid scenario
exits 1 before anything is written."""

from __future__ import annotations

import argparse
from pathlib import Path

from cli.run_flags import add_mode_arguments
from coordinator.compose import ComposeConfig, write_compose

NAME = "compose"
HELP = "write the docker compose file of a scenario's fleet"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario TOML file")
    parser.add_argument("--out", type=Path, default=Path("."),
                        help="directory for compose.yaml, or the .yaml file (default .)")
    add_mode_arguments(parser, "deterministic (default)")
    parser.add_argument("--wait", type=float, default=120.0, metavar="S",
                        help="the coordinator's wait for every service [s] (default 120)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="sim time to run [s] (default: the scenario's duration)")
    parser.add_argument("--insecure", action="store_true",
                        help="plain TCP links, no authentication, no access control (default: "
                             "mutual TLS with the keys of ${TLFLEET_KEYS}, `tlfleet keys "
                             "SCENARIO --out DIR --host router`)")


def run(args: argparse.Namespace) -> int:
    path = write_compose(ComposeConfig(Path(args.scenario), args.out, args.mode, args.wait,
                                       args.duration, secure=not args.insecure))
    print(path)
    return 0
