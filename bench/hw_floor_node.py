"""The floor under the hardware bridge's CPU (bench/hw_bench.py): a bare rclpy node on a lab
file's topics, with none of the bridge's work (no zenoh, no frames, no safety rules).

    python bench/hw_floor_node.py MODE LAB.toml

MODE:

* ``executor``: a subscription per rigid body, served by rclpy's ``SingleThreadedExecutor``
  with a callback that keeps the message — what the plainest rclpy subscriber of the poses costs;
* ``poll``: the same subscriptions taken serialized every 10 ms, the newest per body
  deserialized (the bridge's way, :meth:`tlfleet.sim.hardware.ros_link.RosLink.poll`);
* ``poll_answer``: ``poll`` plus, every 10 ms, one ``TwistStamped``/``Twist`` per robot on its
  command topic (reliable), as the bridge forwards the commands of five robots at 100 Hz.

It runs until SIGTERM/SIGINT; the caller measures its CPU from /proc.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from pathlib import Path

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions
from tlfleet.agent.scenario.lab import load_lab
from tlfleet.sim.hardware.ros_link import CMD_QOS, MOCAP_QOS, message_class

PERIOD = 0.01  # [s] the poll and answer period (the frames' 100 Hz)


def main(mode: str, lab_path: str) -> int:
    lab = load_lab(Path(lab_path))
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    rclpy.init(domain_id=lab.domain_id, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("floor", start_parameter_services=mode == "executor")
    newest: dict[str, object] = {}
    subs = []
    for robot in lab.robots:
        cls = message_class(robot.mocap_type)
        topic = robot.mocap_topic
        subs.append((cls, node.create_subscription(
            cls, topic, lambda msg, topic=topic: newest.__setitem__(topic, msg), MOCAP_QOS,
            raw=mode != "executor")))
    if mode == "executor":
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.1)
    else:
        answers = []
        if mode == "poll_answer":
            for robot in lab.robots:
                cls = message_class(robot.cmd_type)
                answers.append((node.create_publisher(cls, robot.cmd_topic, CMD_QOS), cls()))
        due = time.monotonic()
        while not stop.is_set():
            for cls, sub in subs:
                last = None
                with sub.handle:
                    while (got := sub.handle.take_message(cls, True)) is not None:
                        last = got[0]
                if last is not None:
                    newest[sub.topic_name] = deserialize_message(last, cls)
            for publisher, msg in answers:
                publisher.publish(msg)
            due += PERIOD
            stop.wait(max(0.0, due - time.monotonic()))
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
