"""What every ``tlfleet`` sub-command shares: its help's epilog (examples and exit codes), the
verbosity flags ``-v``/``-q`` wherever they stand, ``-o``/``--out`` and ``--json``.

A command module declares two constants beside ``NAME``, ``HELP``, ``add_arguments`` and ``run``
(tests/project/test_cli_conventions.py checks every public command, and that every example parses):

* ``EXAMPLES``: ``(command line, what it does)`` pairs, each line starting with ``tlfleet NAME``;
* ``EXIT_CODES``: ``{code: meaning}`` of the codes the command itself returns. Usage errors (2,
  argparse's) and Ctrl-C (130) are the same for every command and are added here.

:func:`tlfleet.cli.main.main` builds the epilog from them, so a new command follows the
conventions by filling in two constants, not by formatting text.
"""

from __future__ import annotations

import argparse
import logging
import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path

#: the exit codes every command shares (:func:`tlfleet.cli.main.main`)
COMMON_EXIT_CODES: dict[int, str] = {
    2: "usage error: an unknown flag or a missing argument (argparse)",
    130: "interrupted (Ctrl-C)",
}

#: the usual meaning of 0 and 1, for the commands whose codes are no more than that
SUCCESS_OR_ERROR: dict[int, str] = {
    0: "success",
    1: "an error, printed on stderr as `tlfleet COMMAND: what went wrong`",
}


def epilog(examples: Sequence[tuple[str, str]], exit_codes: Mapping[int, str]) -> str:
    """The text after a sub-command's options: its examples, then every exit code it can return
    (its own and :data:`COMMON_EXIT_CODES`), in ascending order."""
    lines = ["examples:"]
    for command, says in examples:
        lines.append(f"  {command}")
        lines.append(f"      {says}")
    lines.append("")
    lines.append("exit codes:")
    codes = {**COMMON_EXIT_CODES, **exit_codes}
    width = max(len(str(code)) for code in codes)
    for code in sorted(codes):
        lines.extend(textwrap.wrap(codes[code], 96, initial_indent=f"  {code:>{width}}  ",
                                   subsequent_indent=" " * (width + 4)))
    return "\n".join(lines)


def add_verbosity_arguments(parser: argparse.ArgumentParser, *, after_command: bool) -> None:
    """``-v``/``--verbose`` and ``-q``/``--quiet``, both repeatable. The top-level parser and
    every sub-command's parser get them, under different names (argparse would otherwise let the
    sub-command's zero overwrite ``tlfleet -v``'s count); :func:`verbosity` adds them up, so
    ``tlfleet -v run …`` and ``tlfleet run … -v`` mean the same."""
    suffix = "_after" if after_command else ""
    parser.add_argument("-v", "--verbose", dest=f"verbose{suffix}", action="count", default=0,
                        help="more logging: -v info, -vv debug")
    parser.add_argument("-q", "--quiet", dest=f"quiet{suffix}", action="count", default=0,
                        help="less output: no progress bar, errors only in the log")


def merge_verbosity(args: argparse.Namespace) -> None:
    """Fold the sub-command's ``-v``/``-q`` counts into ``args.verbose`` and ``args.quiet``."""
    args.verbose = getattr(args, "verbose", 0) + getattr(args, "verbose_after", 0)
    args.quiet = getattr(args, "quiet", 0) + getattr(args, "quiet_after", 0)


def log_level(args: argparse.Namespace, default: int = logging.WARNING) -> int:
    """``default`` (WARNING; INFO for the fleet's processes, whose log says what they are doing);
    each ``-v`` one level more detail (down to DEBUG), each ``-q`` one less (up to ERROR)."""
    return min(max(default + 10 * (args.quiet - args.verbose), logging.DEBUG), logging.ERROR)


def add_out_argument(parser: argparse.ArgumentParser, help: str, *, default: Path | None = None,
                     required: bool = False, metavar: str = "DIR") -> None:
    """``-o``/``--out``: where a command writes what it makes."""
    parser.add_argument("-o", "--out", type=Path, default=default, required=required,
                        metavar=metavar, help=help)


def add_json_argument(parser: argparse.ArgumentParser,
                      help: str = "print the result as JSON on stdout instead of text") -> None:
    """``--json``: the command's result as one JSON document on stdout (messages stay on
    stderr), for scripts."""
    parser.add_argument("--json", action="store_true", help=help)
