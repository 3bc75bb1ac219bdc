"""``tlfleet completion SHELL``: print a tab-completion script for ``tlfleet`` (shtab).

The script is generated from the parser of every command, so it completes sub-commands, their
flags and file arguments; it is static: source it once (see the examples) and it costs nothing at
each tab.
"""

from __future__ import annotations

import argparse
import sys

NAME = "completion"
HELP = "print a shell completion script (bash, zsh, tcsh)"
SHELLS = ("bash", "zsh", "tcsh")
EXAMPLES = (
    ("tlfleet completion bash > ~/.local/share/bash-completion/completions/tlfleet",
     "install bash completion for your user (new shells pick it up)"),
    ("tlfleet completion zsh > ~/.zfunc/_tlfleet",
     "zsh: with `fpath+=~/.zfunc; autoload -U compinit; compinit` in ~/.zshrc"),
)
EXIT_CODES = {0: "the script was printed",
              1: "shtab is missing (it comes with tlfleet: reinstall the package)"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("shell", choices=SHELLS, help="the shell to complete in")


def run(args: argparse.Namespace) -> int:
    from tlfleet.bus.errors import TlfleetError
    from tlfleet.cli.main import INTERNAL, full_parser

    try:
        import shtab
    except ImportError as exc:
        raise TlfleetError(f"shell completion needs shtab ({exc})") from exc
    parser = full_parser()
    for action in parser._subparsers._group_actions:  # internal commands: not offered either
        for name in INTERNAL:
            action.choices.pop(name, None)
    sys.stdout.write(shtab.complete(parser, shell=args.shell))
    return 0
