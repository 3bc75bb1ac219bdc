"""``tlfleet keys SCENARIO --out DIR [--force] [--host NAME] [--days N] [--mesh]``: a fleet CA,
one key pair and certificate per process and the router's access-control policy
(``tlfleet.coordinator.security.authority``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from tlfleet.cli.arg_types import scenario_file

NAME = "keys"
HELP = "write a fleet CA, per-process certificates and the router's ACL policy"
EXAMPLES = (
    ("tlfleet keys scenario1.toml -o keys/",
     "a CA, one certificate per process of Scenario 1 and the router's policy in keys/"),
    ("tlfleet keys scenario1.toml -o keys/ --host lab-pc.local --days 30",
     "certificates that also name the router's host lab-pc.local, valid for 30 days"),
)
EXIT_CODES = {0: "the keys were written",
              1: "an invalid scenario, or key files exist already (use --force)"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=scenario_file,
                        help="scenario TOML file or a bundled scenario's name")
    parser.add_argument("-o", "--out", type=Path, required=True, metavar="DIR",
                        help="key directory (created; private keys are mode 0600)")
    parser.add_argument("--force", action="store_true", help="overwrite existing key files")
    parser.add_argument("--host", action="append", default=[], metavar="NAME",
                        help="another DNS name or IP address clients use to reach the router "
                             "(repeatable; localhost, 127.0.0.1 and ::1 are always in)")
    parser.add_argument("--days", type=int, default=365,
                        help="validity of the process certificates in days (default 365)")
    parser.add_argument("--mesh", action="store_true",
                        help="several routers linked to each other (a fleet across hosts): the "
                             "policy lets the routers forward each other's traffic")


def run(args: argparse.Namespace) -> int:
    from tlfleet.agent.scenario import load_scenario
    from tlfleet.coordinator.security.authority import write_keys

    keyset = write_keys(load_scenario(args.scenario), args.out, force=args.force,
                        hosts=tuple(args.host), days=args.days, mesh=args.mesh)
    print(f"fleet CA: {keyset.path / 'ca.pem'}  {keyset.fingerprints['ca']}")
    for name in keyset.identities:
        print(f"{name:>12}: {keyset.path / (name + '.pem')}  {keyset.fingerprints[name]}")
    print(f"router policy: {keyset.path / 'acl.json'}")
    print(f"use: tlfleet run SCENARIO --secure {keyset.path}")
    return 0
