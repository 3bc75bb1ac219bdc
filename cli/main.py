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
from types import ModuleType

from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.lifeline import die_with_parent
from tlfleet.cli.conventions import (
    add_verbosity_arguments,
    epilog,
    log_level,
    merge_verbosity,
)

# command name -> (module in tlfleet.cli.commands, one-line help). Kept here so `tlfleet --help`
# lists them without imports. Each module also declares EXAMPLES and EXIT_CODES (the help's
# epilog, tlfleet.cli.conventions).
COMMANDS: dict[str, tuple[str, str]] = {
    "init": ("init", "write a commented starter scenario that passes `tlfleet check`"),
    "check": ("check", "validate a scenario file and summarise it"),
    "schema": ("schema", "print the JSON Schema of scenario files (for editors)"),
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
    "export-mcap": ("export_mcap", "write a run directory as an MCAP file with ROS 2 messages "
                                   "(Foxglove, ros2 bag)"),
    "ros-mirror": ("ros_mirror", "publish a running fleet on ROS 2 for rviz2 and Foxglove "
                                 "(read-only)"),
    "echo": ("echo", "print a running fleet's messages as JSON lines (by key name or pattern)"),
    "topics": ("topics", "list a running fleet's keys (kind, publisher, rate) and its processes"),
    "hz": ("hz", "rates of a running fleet's keys, once a second"),
    "completion": ("completion", "print a shell completion script (bash, zsh, tcsh)"),
}

# Commands the tools run themselves, not people: they work, but `tlfleet --help` does not list
# them (compose-run.sh starts compose-faults).
INTERNAL: frozenset[str] = frozenset({"compose-faults"})


def _version() -> str:
    """The installed distribution's version (pyproject.toml), or "unknown" from a bare tree."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("tlfleet")
    except PackageNotFoundError:
        return "unknown (not installed)"


def build_parser() -> tuple[argparse.ArgumentParser, dict[str, argparse.ArgumentParser]]:
    """The top-level parser and one empty sub-parser per command (their arguments are added by
    :func:`add_command_arguments` when the command is chosen)."""
    parser = argparse.ArgumentParser(
        prog="tlfleet", description="Robot fleets under LTL and STL tasks.",
        epilog="`tlfleet COMMAND --help` shows a command's options, examples and exit codes.")
    add_verbosity_arguments(parser, after_command=False)
    parser.add_argument("--version", action="version", version=f"tlfleet {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers = {}
    for name, (_module, help_text) in COMMANDS.items():
        # a parser made without help= is not listed in `tlfleet --help`
        listed = {} if name in INTERNAL else {"help": help_text}
        subparsers[name] = sub.add_parser(
            name, description=help_text, formatter_class=argparse.RawDescriptionHelpFormatter,
            **listed)
    return parser, subparsers


def command_module(name: str) -> ModuleType:
    """The module of command ``name`` (imported on first use)."""
    return importlib.import_module(f"tlfleet.cli.commands.{COMMANDS[name][0]}")


def add_command_arguments(module: ModuleType, parser: argparse.ArgumentParser) -> None:
    """A command's own arguments, the shared ``-v``/``-q`` and its epilog (examples and exit
    codes, :func:`tlfleet.cli.conventions.epilog`)."""
    module.add_arguments(parser)
    add_verbosity_arguments(parser, after_command=True)
    parser.epilog = epilog(module.EXAMPLES, module.EXIT_CODES)


def full_parser() -> argparse.ArgumentParser:
    """The parser with every command's arguments (shell completion, the conventions test): it
    imports every command module, which ``tlfleet COMMAND`` never does."""
    parser, subparsers = build_parser()
    for name, sub in subparsers.items():
        add_command_arguments(command_module(name), sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    try:
        return _main(argv)
    except KeyboardInterrupt:  # Ctrl-C before a command's own handling (imports, parsing)
        print("tlfleet: interrupted", file=sys.stderr)
        return 130


def _main(argv: Sequence[str] | None) -> int:
    parser, subparsers = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    # Let the chosen command declare its own arguments before the full parse.
    chosen = next((a for a in argv if not a.startswith("-")), None)
    module = None
    if chosen in COMMANDS:
        try:  # importing reads settings from the environment ($TLFLEET_CODEC)
            module = command_module(chosen)
        except TlfleetError as exc:
            print(f"tlfleet {chosen}: {exc}", file=sys.stderr)
            return 1
        add_command_arguments(module, subparsers[chosen])
    args = parser.parse_args(argv)
    if module is None:
        parser.print_help()
        return 2
    merge_verbosity(args)
    die_with_parent()  # started by a coordinator: end with it, even when it is SIGKILLed
    default = getattr(module, "DEFAULT_LOG_LEVEL", logging.WARNING)
    logging.basicConfig(level=log_level(args, default),
                        format="%(levelname)s %(name)s: %(message)s")
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
