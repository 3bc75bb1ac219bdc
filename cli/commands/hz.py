"""``tlfleet hz KEY… [--run RUN_DIR | --fleet F] [--window S] [--duration S] [--json]``: the rate
of each key of a running fleet, once a second, as ``ros2 topic hz`` does: samples a second over
the last ``--window`` seconds, the longest gap between two samples, and the count so far.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from tlfleet.bus.signals import stop_on_signals
from tlfleet.cli.arg_types import positive_float
from tlfleet.cli.conventions import add_json_argument
from tlfleet.cli.fleet_tap import Rates, add_tap_arguments, key_expression, open_tap

NAME = "hz"
HELP = "rates of a running fleet's keys, once a second"
EXAMPLES = (
    ("tlfleet hz mocap 'robot/*/cmd' --run runs/scenario1-20250101-120000",
     "the frame rate and each robot's command rate of a running `tlfleet run`"),
    ("tlfleet hz mocap --fleet scenario1 --duration 10 --json",
     "10 s of rates as JSON lines"),
)
EXIT_CODES = {0: "ended: --duration or Ctrl-C",
              1: "no router answers at the endpoint, or an unreadable run.json / key"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("key", nargs="+", help="key name under the fleet or a full key expression")
    add_tap_arguments(parser)
    parser.add_argument("--window", type=positive_float, default=5.0, metavar="S",
                        help="the rate is measured over the last S seconds (default 5)")
    parser.add_argument("--duration", type=positive_float, default=None, metavar="S",
                        help="stop after S seconds of wall time")
    add_json_argument(parser, "one JSON object a second: {key: {hz, max_gap, count, kind}}")


def run(args: argparse.Namespace) -> int:
    from tlfleet.bus.protocol.codec import peek_kind

    rates = Rates(args.window)
    with open_tap(args) as (transport, fleet), stop_on_signals() as stop:
        for name in args.key:
            transport.subscribe(key_expression(fleet, name),
                                lambda key, payload: rates.add(key, peek_kind(bytes(payload))))
        start = time.monotonic()
        while not stop.wait(1.0):
            report(rates.snapshot(), args.json)
            if args.duration is not None and time.monotonic() - start >= args.duration:
                break
    return 0


def report(snapshot: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps({key: {k: v for k, v in row.items() if k != "from"}
                          for key, row in snapshot.items()}), flush=True)
        return
    if not snapshot:
        print("(nothing received yet)", flush=True)
    for key, row in snapshot.items():
        print(f"{key}: {row['hz']:8.2f} Hz  max gap {1e3 * row['max_gap']:7.1f} ms  "
              f"{row['count']} samples", file=sys.stdout)
    sys.stdout.flush()
