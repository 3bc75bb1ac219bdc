"""``tlfleet report RUN_DIR [--no-figures] [--json]``: regenerate a run's report and figures.

Writes ``report.md``, ``report.json`` and (unless ``--no-figures``) the PNG figures into the run
directory (``tlfleet.coordinator.report.run_report.write_report``), then prints the console table
and the paths, or with ``--json`` the report data. A directory that is not a run directory is a
one-line error and exit code 1 (raised as
:class:`tlfleet.coordinator.report.run_report.RunDirectoryError`, printed by the CLI).
"""

from __future__ import annotations

import argparse
import json
import sys

from tlfleet.cli.run_flags import add_figure_format_argument

NAME = "report"
HELP = "regenerate report.md/json and figures of a run"
EXAMPLES = (
    ("tlfleet report runs/scenario1-20250101-120000",
     "write report.md, report.json and the figures of a run again"),
    ("tlfleet report runs/scenario1-20250101-120000 --figure-format pdf",
     "the figures again as PDF (vector, for a paper)"),
    ("tlfleet report runs/scenario1-20250101-120000 --json --no-figures",
     "print the report's data as JSON, draw no figure"),
)
EXIT_CODES = {0: "the report was written",
              1: "not a run directory, or a damaged one (one line names what the report leaves "
                 "out; it is written from the rest)"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", help="run directory written by `tlfleet run`")
    parser.add_argument("--no-figures", action="store_true", help="skip the figures")
    add_figure_format_argument(parser)
    parser.add_argument("--json", action="store_true",
                        help="print report.json's data instead of the table")


def run(args: argparse.Namespace) -> int:
    from tlfleet.coordinator.record.rundir import damage, json_ready, read_run
    from tlfleet.coordinator.record.typed_json import to_json
    from tlfleet.coordinator.report.render import render_table
    from tlfleet.coordinator.report.run_report import write_report

    files = read_run(args.run_dir)
    report = write_report(files, figures=not args.no_figures, figure_format=args.figure_format)
    if args.json:
        print(json.dumps(json_ready(to_json(report)), indent=2, ensure_ascii=False))
    else:
        print(render_table(report))
        print(f"wrote {report.run_dir / 'report.md'}")
        print(f"wrote {report.run_dir / 'report.json'}")
        for path in report.figure_paths:
            print(f"wrote {path}" if not args.no_figures else f"kept {path}")
    damaged = damage(files)
    if damaged:  # written from what could be read, but the directory is not whole
        print(f"tlfleet report: {args.run_dir}: damaged, the report leaves out {damaged}",
              file=sys.stderr)
        return 1
    return 0


main = run  # the name other command modules' callers may expect
