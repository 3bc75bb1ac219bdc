"""``tlfleet echo KEY… [--run RUN_DIR | --fleet F] [--count N] [--duration S]``: print a running
fleet's messages, one JSON object a line, as ``ros2 topic echo`` or zenoh's ``z_sub`` do.

KEY is a name under the fleet (``mocap``, ``robot/3/status``, ``robot/*/cmd``, ``event/**``, ``**``)
or a full key expression (``tlfleet/scenario1/mocap``); the layout is architecture.md §2. Each
line: ``{"key", "received" (Unix time [s]), "from" (the publisher, from the key layout: events
too, each process has its own event key), "kind", "msg"}``; a payload that is no valid tlfleet
message is printed with its size and why (it is not dropped silently).
"""

from __future__ import annotations

import argparse
import json
import queue
import sys
import time

from tlfleet.bus.signals import stop_on_signals
from tlfleet.cli.arg_types import positive_float, positive_int
from tlfleet.cli.fleet_tap import add_tap_arguments, key_expression, open_tap, sample_line

NAME = "echo"
HELP = "print a running fleet's messages as JSON lines (by key name or pattern)"
EXAMPLES = (
    ("tlfleet echo mocap --run runs/scenario1-20250101-120000 --count 3",
     "three mocap frames of a running `tlfleet run` (its endpoint from run.json)"),
    ("tlfleet echo 'robot/*/status' 'event/**' --fleet scenario1",
     "every robot's status and every event of fleet scenario1 on the usual router port"),
    ("tlfleet echo '**' --fleet lab --secure keys/ --duration 5",
     "everything of a secured fleet for 5 s, as the coordinator's certificate may read it"),
)
EXIT_CODES = {0: "ended: --count samples, --duration, or Ctrl-C",
              1: "no router answers at the endpoint, or an unreadable run.json / key"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("key", nargs="+", help="key name under the fleet or a full key expression")
    add_tap_arguments(parser)
    parser.add_argument("--count", type=positive_int, default=None, metavar="N",
                        help="stop after N samples")
    parser.add_argument("--duration", type=positive_float, default=None, metavar="S",
                        help="stop after S seconds of wall time")


def run(args: argparse.Namespace) -> int:
    inbox: queue.SimpleQueue = queue.SimpleQueue()
    with open_tap(args) as (transport, fleet), stop_on_signals() as stop:
        for name in args.key:
            expr = key_expression(fleet, name)
            transport.subscribe(expr, lambda key, payload: inbox.put((key, payload,
                                                                      time.time())))
        deadline = None if args.duration is None else time.monotonic() + args.duration
        printed = 0
        while not stop.is_set() and (args.count is None or printed < args.count):
            if deadline is not None and time.monotonic() >= deadline:
                break
            try:
                key, payload, received = inbox.get(timeout=0.1)
            except queue.Empty:
                continue
            sys.stdout.write(json.dumps(sample_line(key, payload, received)) + "\n")
            sys.stdout.flush()
            printed += 1
    return 0
