"""``tlfleet router --listen tcp/127.0.0.1:7447``: the fleet's zenoh router (architecture.md §1).

A Python zenoh session in ``router`` mode (stack-notes.md §0: one router, every other process a
client) that declares ``alive/router/0`` and waits for SIGINT/SIGTERM; the session is closed in
``finally``.
"""

from __future__ import annotations

import argparse
import logging
import threading

from agent.protocol import keys
from agent.runtime.transport import (
    add_transport_arguments,
    install_signal_handlers,
    open_transport,
    transport_config,
)

NAME = "router"
HELP = "run a zenoh router for a fleet"

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fleet", default="default",
                        help="fleet name of the liveliness token alive/router/0 (default "
                             "'default'; a scenario's fleet is its [fleet] or its name)")
    add_transport_arguments(parser, default_mode="router")


def run(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    config = transport_config(args)
    if config.mode != "router":
        raise SystemExit(f"tlfleet router: --mode must be router, got {config.mode}")
    if not config.listen:
        raise SystemExit("tlfleet router: give at least one --listen endpoint, "
                         "e.g. tcp/127.0.0.1:7447")
    if stop is None:
        stop = threading.Event()
        install_signal_handlers(stop)
    transport = open_transport(config)
    try:
        transport.declare_alive(keys.alive(args.fleet, "router", 0))
        logger.info("router listening on %s", ", ".join(config.listen))
        while not stop.wait(0.2):
            pass
        return 0
    finally:
        transport.close()
