"""``tlfleet ros-mirror SCENARIO --connect ENDPOINT``: publish a running fleet (simulated or on
real robots) on ROS 2 for rviz2, Foxglove and Nav2, read-only
(:mod:`tlfleet.coordinator.report.ros_mirror`, docs/hardware.md). Needs rclpy (the
``tlfleet[ros2]`` extra, or a ROS 2 installation's Python)."""

from __future__ import annotations

import argparse
import importlib.util
import logging
from pathlib import Path

from tlfleet.bus.errors import TlfleetError
from tlfleet.cli.arg_types import positive_float
from tlfleet.cli.transport_flags import add_transport_arguments, transport_config

NAME = "ros-mirror"
HELP = "publish a running fleet on ROS 2 for rviz2 and Foxglove (read-only)"
DEFAULT_LOG_LEVEL = logging.INFO
EXAMPLES = (
    ("tlfleet ros-mirror scenario1 --connect tcp/127.0.0.1:7447",
     "mirror Scenario 1's fleet on the ROS_DOMAIN_ID of the environment"),
    ("tlfleet ros-mirror my.toml --lab lab.toml --connect tcp/127.0.0.1:7447",
     "on the lab's ROS domain, beside `tlfleet run my.toml --hardware lab.toml`"),
)
EXIT_CODES = {0: "the fleet's run ended (sim_done), or SIGINT / SIGTERM",
              1: "an invalid scenario or lab file, rclpy missing, no router at --connect"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="the fleet's scenario TOML file")
    parser.add_argument("--lab", type=Path, default=None, metavar="LAB.toml",
                        help="publish on this lab file's ROS domain and discovery range")
    parser.add_argument("--domain-id", type=int, default=None, metavar="N",
                        help="ROS domain (default: the lab's, else ROS_DOMAIN_ID)")
    parser.add_argument("--rate", type=positive_float, default=30.0, metavar="HZ",
                        help="poses published at most this often (default 30)")
    parser.add_argument("--prefix", default="/tlfleet", help="topic prefix (default /tlfleet)")
    parser.add_argument("--keep", action="store_true",
                        help="keep running after the fleet's run ends (default: exit at sim_done)")
    add_transport_arguments(parser)


def run(args: argparse.Namespace) -> int:
    if importlib.util.find_spec("rclpy") is None:
        raise TlfleetError("ros-mirror needs rclpy: pip install 'tlfleet[ros2]' or a ROS 2 "
                           "installation's Python (docs/hardware.md)")
    import os
    import threading

    from tlfleet.agent.scenario import load_scenario
    from tlfleet.bus.signals import install_signal_handlers
    from tlfleet.bus.zenoh.transport import open_transport

    scenario = load_scenario(args.scenario)
    domain = args.domain_id
    if args.lab is not None:
        from tlfleet.agent.scenario.lab import load_lab

        lab = load_lab(args.lab)
        os.environ.update(lab.ros_environment())
        domain = lab.domain_id if domain is None else domain
    from tlfleet.coordinator.report.ros_mirror import MirrorConfig, RosMirror

    stop = threading.Event()
    install_signal_handlers(stop)
    transport = open_transport(transport_config(args, "coordinator"))
    try:
        mirror = RosMirror(transport, scenario, MirrorConfig(
            rate=args.rate, prefix=args.prefix, domain_id=domain,
            exit_on_done=not args.keep), stop)
        return mirror.run()
    finally:
        transport.close()
