"""``tlfleet hw SCENARIO --lab LAB.toml``: the hardware bridge, real robots in the simulator's
place (docs/hardware.md, :mod:`tlfleet.sim.hardware.process`); ``--check`` lists what the lab's
topics look like on the ROS 2 graph and exits 0 when the bridge could run on it, 1 otherwise.

Needs rclpy: the ``tlfleet[ros2]`` extra, or a ROS 2 installation's own (``source
/opt/ros/<distro>/setup.bash`` and a virtual environment made with ``--system-site-packages``).
"""

from __future__ import annotations

import argparse
import importlib.util
import logging
from pathlib import Path

from tlfleet.bus.errors import TlfleetError
from tlfleet.cli.arg_types import non_negative_float, positive_float
from tlfleet.cli.process_flags import add_process_arguments, apply_process_flags
from tlfleet.cli.transport_flags import add_transport_arguments, transport_config

NAME = "hw"
HELP = "run the hardware bridge: real robots on ROS 2 in the simulator's place"
# a process's log says what it is doing (waiting for poses, for start) without -v
DEFAULT_LOG_LEVEL = logging.INFO
EXAMPLES = (
    ("tlfleet hw my.toml --lab lab.toml --connect tcp/127.0.0.1:7447",
     "drive the lab's robots for a fleet whose router listens on port 7447"),
    ("tlfleet hw my.toml --lab lab.toml --check",
     "list the lab's mocap and command topics as the ROS graph shows them, with their QoS"),
)
EXIT_CODES = {0: "the run ended (its duration, Control(stop), SIGINT or SIGTERM: every robot was "
                 "sent zero); --check: the graph has what the lab file says",
              1: "an invalid scenario or lab file, rclpy missing, a rigid body without poses, "
                 "no router at --connect; --check: a topic missing or mismatched"}


class RosMissing(TlfleetError):
    """rclpy cannot be imported."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", help="scenario TOML file (the task)")
    parser.add_argument("--lab", type=Path, required=True, metavar="LAB.toml",
                        help="lab file (the hardware: ROS domain, mocap and command topics; "
                             "docs/hardware.md)")
    parser.add_argument("--check", action="store_true",
                        help="list the lab's topics as the ROS graph shows them (publishers, "
                             "subscribers, types, QoS) and the robots' own timeouts; exit 1 when "
                             "the bridge could not run on it")
    parser.add_argument("--check-wait", type=positive_float, default=2.0, metavar="S",
                        help="--check: discovery time before looking [s] (default 2)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="mission time [s] (default: the scenario's duration)")
    parser.add_argument("--max-command-age", type=float, default=None, metavar="S",
                        help="drop commands answering frames older than this [s] (default: 5 "
                             "control periods of the robot)")
    parser.add_argument("--wait-mocap", type=positive_float, default=10.0, metavar="S",
                        help="wall time every rigid body has to send a first pose [s] "
                             "(default 10)")
    parser.add_argument("--backfill-seconds", type=non_negative_float, default=None,
                        metavar="S", help="time of recent frames kept for a recorder's backfill "
                                          "[s] (default 10)")
    add_transport_arguments(parser)
    add_process_arguments(parser)


def _require_rclpy() -> None:
    if importlib.util.find_spec("rclpy") is None:
        raise RosMissing("rclpy is not installed: install the ROS 2 extra (pip install "
                         "'tlfleet[ros2]') or use a ROS 2 installation's Python "
                         "(docs/hardware.md)")


def check(args: argparse.Namespace) -> int:
    from tlfleet.agent.scenario import load_scenario
    from tlfleet.agent.scenario.lab import check_lab, load_lab
    from tlfleet.sim.hardware.ros_link import graph_report

    lab = load_lab(args.lab)
    check_lab(lab, load_scenario(args.scenario))
    rows = graph_report(lab, wait=args.check_wait)
    print(f"ROS domain {lab.domain_id}, discovery {lab.discovery_range}, world frame "
          f"{lab.world_frame!r}")
    bad = 0
    for row in rows:
        who = "publishers" if row.role == "mocap" else "subscribers"
        status = "ok" if not row.problems else "PROBLEM: " + "; ".join(row.problems)
        bad += bool(row.problems)
        print(f"robot {row.robot} {row.role:5s} {row.topic} [{row.expected_type}]: "
              f"{len(row.endpoints)} {who} — {status}")
        for e in row.endpoints:
            print(f"    {e.node}  {e.type}  {e.reliability}/{e.durability}")
    print("if the bridge crashes, each robot stops on its own command timeout:")
    for robot in lab.robots:
        timeout = (f"{robot.robot_timeout:g} s" if robot.robot_timeout is not None
                   else "not recorded in the lab file (robot_timeout): check the robot's "
                        "driver")
        print(f"    robot {robot.id} ({robot.cmd_topic}): {timeout}; keep-alive every "
              f"{1.0 / robot.repeat_hz:g} s")
    return 1 if bad else 0


def run(args: argparse.Namespace) -> int:
    _require_rclpy()
    if args.check:
        return check(args)
    from tlfleet.sim.hardware.process import BridgeProcessConfig, main

    config = BridgeProcessConfig(
        scenario=Path(args.scenario), lab=args.lab, duration=args.duration,
        transport=transport_config(args, "sim"), max_command_age=args.max_command_age,
        wait_mocap=args.wait_mocap,
        **({} if args.backfill_seconds is None else {"backfill_seconds": args.backfill_seconds}))
    apply_process_flags(args, "hw")
    return main(config)
