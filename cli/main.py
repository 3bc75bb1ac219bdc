"""The ``tlfleet`` command line: one sub-command per module in ``tlfleet.cli.commands``.

Each command module exposes ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``.
Modules are imported only when their command runs, so ``tlfleet agent`` never pays for the
coordinator's viewers, and a broken optional dependency cannot take the whole CLI down.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
from collections.abc import Sequence

from tlfleet.bus.errors import TlfleetError

# command name -> (module in tlfleet.cli.commands, one-line help). Kept here so `tlfleet --help`
# lists them without imports.
COMMANDS: dict[str, tuple[str, str]] = {
    "check": ("check", "validate a scenario file and summarise it"),
    "translate": ("translate", "LTL formula to Büchi automaton"),
    "plan": ("plan", "optimal prefix–suffix plans of the LTL robots"),
    "monitor": ("monitor", "STL robustness of a recorded trajectory"),
    "router": ("router", "run a zenoh router for a fleet"),
    "sim": ("sim", "run the pymunk simulator process of a scenario"),
    "hw": ("hw", "run the hardware bridge: real robots on ROS 2 in the simulator's place"),
    "agent": ("agent", "run the agent process of one robot"),
    "run": ("run", "launch, supervise and record a whole fleet"),
    "keys": ("keys", "write a fleet CA, per-process certificates and the router's ACL policy"),
    "supervise": ("supervise",
                  "join a running fleet: wait for it, start, supervise and record the run"),
    "compose": ("compose", "write the docker compose file of a scenario's fleet"),
    "compose-faults": ("compose_faults", "the host's side of a compose fleet's faults (run by "
                                         "compose-run.sh)"),
    "report": ("report", "regenerate report.md/json and figures of a run"),
    "replay": ("replay", "re-log a finished run to rerun (run.rrd, --viewer)"),
}


def _version() -> str:
    """The installed distribution's version (pyproject.toml), or "unknown" from a bare tree."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("tlfleet")
    except PackageNotFoundError:
        return "unknown (not installed)"


def build_parser() -> tuple[argparse.ArgumentParser, dict[str, argparse.ArgumentParser]]:
    parser = argparse.ArgumentParser(
        prog="tlfleet", description="Robot fleets under LTL and STL tasks."
    )
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more logging")
    parser.add_argument("--version", action="version", version=f"tlfleet {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers = {}
    for name, (_module, help_text) in COMMANDS.items():
        subparsers[name] = sub.add_parser(name, help=help_text, description=help_text)
    return parser, subparsers


def main(argv: Sequence[str] | None = None) -> int:
    parser, subparsers = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    # Let the chosen command declare its own arguments before the full parse.
    chosen = next((a for a in argv if not a.startswith("-")), None)
    module = None
    if chosen in COMMANDS:
        try:  # importing reads settings from the environment ($TLFLEET_CODEC)
            module = importlib.import_module(f"tlfleet.cli.commands.{COMMANDS[chosen][0]}")
        except TlfleetError as exc:
            print(f"tlfleet {chosen}: {exc}", file=sys.stderr)
            return 1
        module.add_arguments(subparsers[chosen])
    args = parser.parse_args(argv)
    if module is None:
        parser.print_help()
        return 2
    logging.basicConfig(
        level=logging.WARNING - 10 * args.verbose, format="%(levelname)s %(name)s: %(message)s"
    )
    try:
        return int(module.run(args) or 0)
    except TlfleetError as exc:
        print(f"tlfleet {args.command}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"tlfleet {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (`tlfleet plan ... | head`): not an error; silence the final flush
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
