"""``tlfleet translate 'FORMULA' | -F FILE | --hoa FILE [--format hoa|text|dot] [--stats]``.

Prints the automaton of ``tlfleet.agent.ltl.buchi.translate`` (ltl-planning.md §2) on stdout — HOA
v1 by default, so it can be piped into Spot's ``autfilt`` — and its size and translation time on
stderr.
``-F FILE`` translates one formula per line (``tlfleet.agent.ltl.batch``, like ``ltl2tgba -F``);
``--stats`` prints one tab-separated line per formula (states, edges, time) instead of the
automata; ``--hoa FILE`` reads an automaton made by another tool (``tlfleet.agent.ltl.hoa_reader``).
``--json`` prints the automaton as one JSON object (with ``-F``, one object a line, JSON Lines):
``formula``, ``atoms``, ``initial``, ``accepting`` and ``edges`` as ``[source, target, guard]``
with the guard in Spot's syntax over the atoms.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from tlfleet.agent.ltl.batch import STATS_HEADER, read_formulas, stats_line, translate_all
from tlfleet.agent.ltl.buchi import to_dot, to_text, translate
from tlfleet.agent.ltl.hoa import to_hoa
from tlfleet.agent.ltl.hoa_reader import read_hoa_file
from tlfleet.bus.errors import LtlError
from tlfleet.bus.limits import MEMORY_LIMIT, TIME_LIMIT, bounded
from tlfleet.cli.arg_types import positive_float, positive_int
from tlfleet.cli.conventions import add_json_argument

NAME = "translate"
HELP = "translate an LTL formula to a Büchi automaton"
EXAMPLES = (
    ("tlfleet translate 'G F a & G F b'", "the Büchi automaton in HOA v1 (pipe it to autfilt)"),
    ("tlfleet translate 'F (a & F b)' --json", "the automaton as JSON"),
    ("tlfleet translate -F formulas.txt --stats", "states, edges and time of each line's formula"),
)
EXIT_CODES = {0: "translated", 1: "a formula does not parse (line and column on stderr)"}

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
    add_json_argument(parser, "print the automaton (or the --stats figures) as JSON instead; "
                              "with -F one JSON object a line")
    add_limit_arguments(parser, "one formula's translation (or reading the HOA file)")


def add_limit_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--time-limit", type=positive_float, default=TIME_LIMIT, metavar="S",
                        help=f"wall time {what} may take [s] (default {TIME_LIMIT:g})")
    parser.add_argument("--memory-limit", type=positive_int, default=MEMORY_LIMIT,
                        metavar="MB", help=f"memory {what} may add [MB] (default "
                                           f"{MEMORY_LIMIT})")


def _bound(args: argparse.Namespace, what: str):
    return bounded(what, args.time_limit, args.memory_limit,
                   " (raise --time-limit / --memory-limit)")


def automaton_json(buchi) -> dict:
    """The automaton as plain data (``--json``)."""
    return {"formula": buchi.formula, "atoms": list(buchi.atoms), "states": buchi.num_states,
            "initial": list(buchi.initial), "accepting": sorted(buchi.accepting),
            "edges": [[q, dst, buchi.guard_text(guard)] for q, out in enumerate(buchi.edges)
                      for dst, guard in out]}


def _stats_json(buchi, seconds: float) -> dict:
    return {"formula": buchi.formula, "states": buchi.num_states, "edges": buchi.num_edges,
            "accepting": len(buchi.accepting), "initial": len(buchi.initial),
            "ms": round(1e3 * seconds, 3)}


def _write(buchi, args: argparse.Namespace) -> None:
    if args.json:
        print(json.dumps(automaton_json(buchi)))
    elif args.format == "hoa":
        sys.stdout.write(to_hoa(buchi, name=args.name))
    elif args.format == "text":
        sys.stdout.write(to_text(buchi))
    else:
        sys.stdout.write(to_dot(buchi))


def _run_file(args: argparse.Namespace) -> int:
    failed = 0
    if args.stats and not args.json:
        print(STATS_HEADER)
    for result in translate_all(read_formulas(args.file),
                                bound=lambda: _bound(args, "translation")):
        if result.error is not None:
            failed += 1
            print(f"tlfleet translate: {args.file}:{result.line}: {result.error}",
                  file=sys.stderr)
        if args.json and result.buchi is None:
            print(json.dumps({"line": result.line, "formula": result.formula,
                              "error": str(result.error)}))
        elif args.json and args.stats:
            print(json.dumps({"line": result.line,
                              **_stats_json(result.buchi, result.cpu_seconds)}))
        elif args.stats:
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
    with _bound(args, "reading the HOA file" if args.hoa is not None else "translation"):
        buchi = read_hoa_file(args.hoa) if args.hoa is not None else translate(args.formula)
    elapsed = time.perf_counter() - t0
    if args.stats and args.json:
        print(json.dumps(_stats_json(buchi, elapsed)))
        return 0
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
