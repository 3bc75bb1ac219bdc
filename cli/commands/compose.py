"""``tlfleet compose SCENARIO [--out DIR|FILE.yaml] [--lockstep|--realtime] [--insecure]
[--lease-ms MS] [--fault SPEC …] [--fault-subnet CIDR]``: write the docker compose file of a
scenario's fleet (:mod:`tlfleet.coordinator.compose`), secured by default (mutual TLS, the router's
access control; keys from ``${TLFLEET_KEYS}``). With faults (``--fault`` or the scenario's
``[[faults]]``) the coordinator hands them to the host's executor that ``make compose-run``
starts (:mod:`tlfleet.coordinator.faults.handoff`). An invalid scenario or a fault a compose fleet
cannot do (a partition, a host) exits 1 before anything is written."""

from __future__ import annotations

import argparse
from pathlib import Path

from tlfleet.cli.arg_types import fault_spec, scenario_file
from tlfleet.cli.run_flags import add_mode_arguments
from tlfleet.cli.transport_flags import add_lease_argument
from tlfleet.coordinator.compose import FAULT_SUBNET, ComposeConfig, write_compose

NAME = "compose"
HELP = "write the docker compose file of a scenario's fleet"
EXAMPLES = (
    ("tlfleet compose scenario1.toml -o fleet/",
     "write fleet/compose.yaml: one service per process of Scenario 1, mutual TLS"),
    ("tlfleet compose scenario1.toml -o fleet/ --insecure --realtime",
     "the same fleet on plain TCP, physics on wall-clock time"),
)
EXIT_CODES = {0: "the compose file was written",
              1: "an invalid scenario, or a fault a compose fleet cannot do"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=scenario_file,
                        help="scenario TOML file or a bundled scenario's name")
    parser.add_argument("-o", "--out", type=Path, default=Path("."),
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
    add_lease_argument(parser, "every service's")
    parser.add_argument("--fault-subnet", default=FAULT_SUBNET, metavar="CIDR",
                        help="with faults: the fleet network's IPv4 subnet, the router at its "
                             f".2 (default {FAULT_SUBNET}; pick another when docker says the "
                             "pool overlaps)")
    parser.add_argument("--fault", dest="faults", type=fault_spec, action="append", default=[],
                        metavar="SPEC",
                        help="inject a fault (repeatable, as `tlfleet run --fault`): cut (docker "
                             "network disconnect/connect), freeze (docker pause/unpause), kill, "
                             "restart (agents); no partitions, no hosts")


def run(args: argparse.Namespace) -> int:
    from tlfleet.coordinator.supervise import load_checked

    # the one load of the file: checked as `tlfleet run` checks it (an agent that could not
    # launch is refused here, not in its container), then rendered
    scenario = load_checked(Path(args.scenario))
    path = write_compose(ComposeConfig(Path(args.scenario), args.out, args.mode, args.wait,
                                       args.duration, insecure=args.insecure,
                                       faults=tuple(args.faults), lease_ms=args.lease_ms,
                                       fault_subnet=args.fault_subnet), scenario)
    print(path)
    return 0
