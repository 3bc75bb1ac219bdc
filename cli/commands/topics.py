"""``tlfleet topics [--run RUN_DIR | --fleet F] [--listen-for S] [--json]``: what a running fleet
publishes and who is in it: listens to every key of the fleet for a few seconds, then prints each
key with its message kind, its publisher (from the key layout, architecture.md §2), its rate and
count, and the processes present (their liveliness tokens), as ``ros2 topic list -v`` does.
"""

from __future__ import annotations

import argparse
import json
import threading

from tlfleet.bus.protocol import keys
from tlfleet.bus.signals import stop_on_signals
from tlfleet.cli.arg_types import positive_float
from tlfleet.cli.conventions import add_json_argument
from tlfleet.cli.fleet_tap import Rates, add_tap_arguments, key_expression, open_tap

NAME = "topics"
HELP = "list a running fleet's keys (kind, publisher, rate) and its processes"
EXAMPLES = (
    ("tlfleet topics --run runs/scenario1-20250101-120000",
     "the keys and processes of a running `tlfleet run`"),
    ("tlfleet topics --fleet lab --listen-for 5 --json", "5 s of listening, the result as JSON"),
)
EXIT_CODES = {0: "listed (possibly nothing: a fleet that publishes nothing is not an error)",
              1: "no router answers at the endpoint, or an unreadable run.json"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_tap_arguments(parser)
    parser.add_argument("--listen-for", type=positive_float, default=2.0, metavar="S",
                        help="how long to listen before listing [s] (default 2)")
    add_json_argument(parser, "print {keys: {key: {kind, from, hz, count}}, processes: [...]}")


def run(args: argparse.Namespace) -> int:
    from tlfleet.bus.protocol.codec import peek_kind

    rates = Rates(args.listen_for)
    present: dict[str, bool] = {}
    lock = threading.Lock()

    def on_alive(key: str, alive: bool) -> None:
        with lock:
            present[key] = alive

    with open_tap(args) as (transport, fleet), stop_on_signals() as stop:
        transport.subscribe(key_expression(fleet, "**"),
                            lambda key, payload: rates.add(key, peek_kind(bytes(payload))))
        transport.watch_alive(key_expression(fleet, "alive/**"), on_alive)
        stop.wait(args.listen_for)
    snapshot = {key: row for key, row in rates.snapshot().items()
                if keys.parse_alive(key) is None}
    with lock:
        processes = sorted(keys.publisher_of(k) for k, alive in present.items() if alive)
    if args.json:
        print(json.dumps({"keys": {k: {"kind": r["kind"], "from": r["from"], "hz": r["hz"],
                                       "count": r["count"]} for k, r in snapshot.items()},
                          "processes": processes}, indent=2))
        return 0
    if not snapshot:
        print(f"nothing published in {args.listen_for:g} s")
    width = max((len(k) for k in snapshot), default=0)
    for key, row in snapshot.items():
        print(f"{key:<{width}}  {row['kind'] or '?':<12} from {row['from']:<12} "
              f"{row['hz']:8.2f} Hz  ({row['count']} samples)")
    print("processes: " + (", ".join(processes) if processes else "none"))
    return 0
