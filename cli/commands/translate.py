"""``tlfleet translate 'FORMULA' | -F FILE | --hoa FILE [--format hoa|text|dot] [--stats]``.

Prints the automaton of ``tlfleet.agent.ltl.buchi.translate`` (ltl-planning.md §2) on stdout — HOA
v1 by default, so it can be piped into Spot's ``autfilt`` — and its size and translation time on
stderr.
``-F FILE`` translates one formula per line (``tlfleet.agent.ltl.batch``, like ``ltl2tgba -F``);
``--stats`` prints one tab-separated line per formula (states, edges, time) instead of the
automata; ``--hoa FILE`` reads an automaton made by another tool (``tlfleet.agent.ltl.hoa_reader``).
"""

from __future__ import annotations

import argparse
import sys
import time

from tlfleet.agent.ltl.batch import STATS_HEADER, read_formulas, stats_line, translate_all
from tlfleet.agent.ltl.buchi import to_dot, to_text, translate
from tlfleet.agent.ltl.hoa import to_hoa
from tlfleet.agent.ltl.hoa_reader import read_hoa_file
from tlfleet.bus.errors import LtlError

NAME = "translate"
HELP = "translate an LTL formula to a Büchi automaton"

_FORMATS = ("hoa", "text", "dot")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("formula", nargs="?", default=None,
                        help="LTL formula in Spot syntax, e.g. 'G F a & G F b'")
    parser.add_argument("-F", "--file", default=None,
                        help="translate every line of FILE (one formula a line, # comments)")
    parser.add_argument("--hoa", default=None, metavar="FILE",
                        help="read a HOA v1 Büchi automaton instead of translating a formula")
    parser.add_argument("--stats", action="store_true",
                        help="print states/edges/time per formula instead of the automata")
    parser.add_argument("--format", choices=_FORMATS, default="hoa",
                        help="output format (default: hoa)")
    parser.add_argument("--name", default=None, help="automaton name in the HOA output")


def _write(buchi, args: argparse.Namespace) -> None:
    if args.format == "hoa":
        sys.stdout.write(to_hoa(buchi, name=args.name))
    elif args.format == "text":
        sys.stdout.write(to_text(buchi))
    else:
        sys.stdout.write(to_dot(buchi))


def _run_file(args: argparse.Namespace) -> int:
    failed = 0
    if args.stats:
        print(STATS_HEADER)
    for result in translate_all(read_formulas(args.file)):
        if result.error is not None:
            failed += 1
            print(f"tlfleet translate: {args.file}:{result.line}: {result.error}",
                  file=sys.stderr)
        if args.stats:
            print(stats_line(result))
        elif result.buchi is not None:
            _write(result.buchi, args)
    return 1 if failed else 0


def run(args: argparse.Namespace) -> int:
    given = [x for x in (args.formula, args.file, args.hoa) if x is not None]
    if len(given) != 1:
        raise LtlError("give exactly one of FORMULA, -F FILE or --hoa FILE")
    if args.file is not None:
        return _run_file(args)
    t0 = time.perf_counter()
    buchi = read_hoa_file(args.hoa) if args.hoa is not None else translate(args.formula)
    elapsed = time.perf_counter() - t0
    if args.stats:
        print(f"{buchi.num_states}\t{buchi.num_edges}\t{1e3 * elapsed:.3f}\t{buchi.formula}")
        return 0
    _write(buchi, args)
    print(
        f"{buchi.num_states} states, {buchi.num_edges} edges, {len(buchi.accepting)} accepting "
        f"({1e3 * elapsed:.2f} ms)",
        file=sys.stderr,
    )
    return 0
