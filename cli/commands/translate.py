"""``tlfleet translate 'FORMULA' [--format hoa|text|dot]``: LTL → Büchi automaton.

Prints the automaton of ``agent.ltl.buchi.translate`` (ltl-planning.md §2) on stdout — HOA v1 by
default, so it can be piped into Spot's ``autfilt`` — and its size and translation time on stderr.
"""

from __future__ import annotations

import argparse
import sys
import time

from agent.ltl.buchi import to_dot, to_text, translate
from agent.ltl.hoa import to_hoa

NAME = "translate"
HELP = "translate an LTL formula to a Büchi automaton"

_FORMATS = ("hoa", "text", "dot")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("formula", help="LTL formula in Spot syntax, e.g. 'G F a & G F b'")
    parser.add_argument("--format", choices=_FORMATS, default="hoa",
                        help="output format (default: hoa)")
    parser.add_argument("--name", default=None, help="automaton name in the HOA output")


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    buchi = translate(args.formula)
    elapsed = time.perf_counter() - t0
    if args.format == "hoa":
        sys.stdout.write(to_hoa(buchi, name=args.name))
    elif args.format == "text":
        sys.stdout.write(to_text(buchi))
    else:
        sys.stdout.write(to_dot(buchi))
    print(
        f"{buchi.num_states} states, {buchi.num_edges} edges, {len(buchi.accepting)} accepting "
        f"({1e3 * elapsed:.2f} ms)",
        file=sys.stderr,
    )
    return 0
