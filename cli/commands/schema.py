"""``tlfleet schema [--out FILE]``: the JSON Schema of a scenario file, generated from the model.

An editor with a TOML language server (Taplo, Even Better TOML) completes keys and flags wrong
types from it: write ``tlfleet schema --out scenario.schema.json`` and start the scenario file
with the line ``#:schema ./scenario.schema.json``. What a schema cannot say — geometry, formulas,
windows, plans — ``tlfleet check`` checks (:mod:`tlfleet.agent.scenario.reference`,
docs/scenario.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tlfleet.agent.scenario.reference import json_schema

NAME = "schema"
HELP = "print the JSON Schema of scenario files (for editors)"
EXAMPLES = (
    ("tlfleet schema --out scenario.schema.json",
     "write it, then start a scenario with '#:schema ./scenario.schema.json'"),
)
EXIT_CODES = {0: "printed or written"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=None, metavar="FILE",
                        help="write the schema to FILE instead of stdout")


def run(args: argparse.Namespace) -> int:
    text = json.dumps(json_schema(), indent=2, ensure_ascii=False) + "\n"
    if args.out is None:
        print(text, end="")
    else:
        args.out.write_text(text, encoding="utf-8")
    return 0
