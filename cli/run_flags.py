"""The flags of the commands that make or record a run (``run``, ``supervise``, ``compose``):
the time mode and the outputs written at the end (style.md §6: one definition, one wording)."""

from __future__ import annotations

import argparse


def add_mode_arguments(parser: argparse.ArgumentParser,
                       lockstep_help: str = "deterministic, faster than real time (default)",
                       realtime_help: str = "physics on wall-clock time") -> None:
    """``--lockstep`` (default) / ``--realtime`` → ``args.mode``."""
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--lockstep", dest="mode", action="store_const", const="lockstep",
                      help=lockstep_help)
    mode.add_argument("--realtime", dest="mode", action="store_const", const="realtime",
                      help=realtime_help)
    parser.set_defaults(mode="lockstep")


def add_output_arguments(parser: argparse.ArgumentParser) -> None:
    """``--no-report``, ``--no-figures``, ``--no-rrd`` → ``args.report``, ``.figures``, ``.rrd``."""
    parser.add_argument("--no-report", dest="report", action="store_false",
                        help="do not write report.md/json and figures at the end")
    parser.add_argument("--no-figures", dest="figures", action="store_false",
                        help="write report.md/json but no figures")
    add_figure_format_argument(parser)
    parser.add_argument("--no-rrd", dest="rrd", action="store_false",
                        help="do not write run.rrd (rerun) at the end")


def add_figure_format_argument(parser: argparse.ArgumentParser) -> None:
    """``--figure-format png|pdf|svg`` → ``args.figure_format``."""
    parser.add_argument("--figure-format", choices=("png", "pdf", "svg"), default="png",
                        help="the figures' format: png (200 dpi, default: shown in report.md "
                             "everywhere), or pdf / svg (vector, for a paper)")
