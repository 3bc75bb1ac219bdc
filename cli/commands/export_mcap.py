"""``tlfleet export-mcap RUN_DIR [-o FILE]``: a recorded run as an MCAP file with ROS 2 encodings
for Foxglove and ``ros2 bag`` (:mod:`tlfleet.coordinator.report.mcap_export`, docs/hardware.md).
Needs the ``mcap`` and ``mcap-ros2-support`` packages (the ``tlfleet[ros2]`` extra), not ROS."""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

from tlfleet.bus.errors import TlfleetError
from tlfleet.cli.conventions import SUCCESS_OR_ERROR, add_out_argument

NAME = "export-mcap"
HELP = "write a run directory as an MCAP file with ROS 2 messages (Foxglove, ros2 bag)"
EXAMPLES = (
    ("tlfleet export-mcap runs/scenario1-20260101-120000",
     "write runs/scenario1-20260101-120000/run.mcap"),
    ("tlfleet export-mcap runs/try1 -o try1.mcap", "write it elsewhere"),
)
EXIT_CODES = SUCCESS_OR_ERROR


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", type=Path, help="a run directory (tlfleet run --out)")
    add_out_argument(parser, "the MCAP file (default RUN_DIR/run.mcap)", metavar="FILE")


def run(args: argparse.Namespace) -> int:
    if importlib.util.find_spec("mcap_ros2") is None:
        raise TlfleetError("export-mcap needs the mcap and mcap-ros2-support packages: pip "
                           "install 'tlfleet[ros2]'")
    from tlfleet.coordinator.report.mcap_export import export_mcap

    path = export_mcap(args.run_dir, args.out)
    print(path)
    return 0
