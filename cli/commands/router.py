"""``tlfleet router --listen tcp/127.0.0.1:7447``: the fleet's zenoh router
(``tlfleet.sim.router.process``)."""

from __future__ import annotations

import argparse
import logging
import threading

from tlfleet.cli.process_flags import add_process_arguments, apply_process_flags
from tlfleet.cli.transport_flags import add_transport_arguments, transport_config
from tlfleet.sim.router.process import RouterConfig, RouterConfigError

NAME = "router"
HELP = "run a zenoh router for a fleet"
# a process's log says what it is doing (waiting for start, listening, ...) without -v;
# -q leaves the warnings only (tlfleet.cli.conventions.log_level)
DEFAULT_LOG_LEVEL = logging.INFO
EXAMPLES = (
    ("tlfleet router --fleet scenario1 --listen tcp/127.0.0.1:7447",
     "a router for the fleet `scenario1` on port 7447 of this machine"),
)
EXIT_CODES = {0: "stopped by SIGINT or SIGTERM", 1: "a bad configuration, or the port is taken"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fleet", default="default",
                        help="fleet name of the liveliness token alive/router/0 (default "
                             "'default'; a scenario's fleet is its [fleet] or its name)")
    add_transport_arguments(parser, default_mode="router")
    add_process_arguments(parser)


def run(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    from tlfleet.sim.router.process import main

    try:
        config = RouterConfig(fleet=args.fleet, transport=transport_config(args, "router"))
    except RouterConfigError as exc:
        raise SystemExit(f"tlfleet router: {exc}") from None
    apply_process_flags(args, "router")
    return main(config, stop)
