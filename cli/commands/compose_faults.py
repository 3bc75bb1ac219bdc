"""``tlfleet compose-faults --dir RUN/logs/faults --project P [--parent PID] [--max-wall S]``: the
host's side of the faults of a compose fleet (:mod:`tlfleet.coordinator.faults.docker_executor`):
answers the coordinator's requests with docker commands on project P's containers until ``--parent``
is gone or ``--max-wall`` seconds have passed (``docker/compose-run.sh`` starts it in the background
and stops it in its clean-up). Stops on SIGINT/SIGTERM, undoing what is still in effect."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from tlfleet.bus.signals import stop_on_signals
from tlfleet.cli.arg_types import positive_float

NAME = "compose-faults"
HELP = "the host's side of a compose fleet's faults (docker commands; run by compose-run.sh)"
EXAMPLES = (
    ("tlfleet compose-faults --dir runs/r1/logs/faults --project fleet1",
     "carry out the coordinator's fault requests on project fleet1's containers"),
)
EXIT_CODES = {0: "its parent ended, --max-wall passed, or SIGINT/SIGTERM",
              1: "the handoff directory cannot be read"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dir", type=Path, required=True, metavar="DIR",
                        help="the handoff directory: the run directory's logs/faults")
    parser.add_argument("--project", required=True, metavar="P",
                        help="the compose project whose containers the faults target")
    parser.add_argument("--parent", type=int, default=None, metavar="PID",
                        help="end when this process is gone (the script that started us)")
    parser.add_argument("--max-wall", type=positive_float, default=3600.0, metavar="S",
                        help="end after S seconds of wall time at most (default 3600)")


def run(args: argparse.Namespace) -> int:
    from tlfleet.coordinator.faults.docker_executor import Executor, serve

    logging.getLogger("tlfleet.coordinator.faults.docker_executor").setLevel(logging.INFO)
    with stop_on_signals() as stop:
        handled = serve(args.dir, Executor(args.project), parent=args.parent,
                        max_wall=args.max_wall, stop=stop.is_set)
    print(f"compose-faults: {handled} request(s) handled", flush=True)
    return 0
