"""Kinematic fake robots as real rclpy nodes, for the hardware bridge's tests and bench.

``python fake_robots.py CONFIG.json`` runs one node per robot of the config in one process:

* a **unicycle** (TurtleBot-like) integrates ``(linear.x, angular.z)``; a **mecanum** car
  integrates the body-frame ``(linear.x, linear.y, angular.z)`` rotated into the world frame by its
  heading (REP 103); the velocity follows the command within acceleration limits;
* each takes ``Twist`` or ``TwistStamped`` on its command topic (a reliable subscription, as
  ros2_controllers', or best effort) and has its **own command timeout**: no command for
  ``cmd_timeout`` seconds → it brakes to rest, as a Create 3 or ``diff_drive_controller`` does;
* it publishes its rigid body like ``vrpn_mocap``: ``PoseStamped`` on ``/vrpn_mocap/<name>/pose``
  (frame ``world``, best-effort sensor-data QoS, or reliable) at ``rate`` Hz, with Gaussian
  position/heading ``noise``, a ``latency`` [s], a ``dropout`` probability per pose, and a body
  that is **lost** (no pose any more) ``lose_after`` seconds after its first command.

Every command received is appended to ``log`` as a JSON line ``{"robot", "t", "u", "stamp"}`` with
``t`` = CLOCK_MONOTONIC at reception (the same clock as every process on the machine), so a test
can tell when a zero command arrived against when the bridge exited. SIGTERM/SIGINT end it.
"""

from __future__ import annotations

import json
import math
import random
import signal
import sys
import threading
import time
from collections import deque
from pathlib import Path

import rclpy
from geometry_msgs.msg import PoseStamped, Twist, TwistStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions


def qos(reliable: bool, depth: int = 10) -> QoSProfile:
    return QoSProfile(reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE, history=HistoryPolicy.KEEP_LAST,
                      depth=depth)


class FakeRobot:
    def __init__(self, node, spec: dict, log, lock: threading.Lock):
        self.node = node
        self.name = spec["name"]
        self.kind = spec["kind"]  # unicycle | mecanum
        self.x, self.y, self.yaw = (float(v) for v in spec["pose"])
        self.v = [0.0, 0.0, 0.0]  # body-frame velocity (vx, vy, ω)
        self.target = [0.0, 0.0, 0.0]
        self.acc_lin = float(spec.get("acc_lin", 2.0))
        self.acc_ang = float(spec.get("acc_ang", 8.0))
        self.cmd_timeout = float(spec.get("cmd_timeout", 0.5))
        self.noise = float(spec.get("noise", 0.0))
        self.latency = float(spec.get("latency", 0.0))
        self.dropout = float(spec.get("dropout", 0.0))
        self.lose_after = spec.get("lose_after")
        self.rng = random.Random(spec.get("seed", 0))
        self.last_cmd = -math.inf
        self.first_cmd: float | None = None
        self.queue: deque = deque()
        self.log, self.lock = log, lock
        stamped = spec.get("cmd_type", "geometry_msgs/msg/TwistStamped").endswith("Stamped")
        self.stamped = stamped
        node.create_subscription(TwistStamped if stamped else Twist, spec["cmd_topic"],
                                 self.on_cmd, qos(spec.get("cmd_reliable", True)))
        self.pub = node.create_publisher(
            PoseStamped, spec.get("mocap_topic", f"/vrpn_mocap/{self.name}/pose"),
            qos(spec.get("mocap_reliable", False), depth=5))

    def on_cmd(self, msg) -> None:
        now = time.monotonic()
        body = msg.twist if self.stamped else msg
        self.target = [body.linear.x, body.linear.y if self.kind == "mecanum" else 0.0,
                       body.angular.z]
        self.last_cmd = now
        if self.first_cmd is None:
            self.first_cmd = now
        stamp = None
        if self.stamped:
            stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        with self.lock:
            self.log.write(json.dumps({"robot": self.name, "t": now, "u": self.target,
                                       "stamp": stamp}) + "\n")
            self.log.flush()

    def step(self, dt: float, now: float) -> None:
        target = self.target if now - self.last_cmd <= self.cmd_timeout else [0.0, 0.0, 0.0]
        for i, acc in ((0, self.acc_lin), (1, self.acc_lin), (2, self.acc_ang)):
            dv = max(-acc * dt, min(acc * dt, target[i] - self.v[i]))
            self.v[i] += dv
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        self.x += (c * self.v[0] - s * self.v[1]) * dt
        self.y += (s * self.v[0] + c * self.v[1]) * dt
        self.yaw = math.atan2(math.sin(self.yaw + self.v[2] * dt),
                              math.cos(self.yaw + self.v[2] * dt))

    def sample(self, now: float) -> None:
        if self.lose_after is not None and self.first_cmd is not None \
                and now - self.first_cmd >= float(self.lose_after):
            return
        if self.dropout and self.rng.random() < self.dropout:
            return
        n = self.noise
        pose = (self.x + self.rng.gauss(0.0, n) if n else self.x,
                self.y + self.rng.gauss(0.0, n) if n else self.y,
                self.yaw + self.rng.gauss(0.0, n) if n else self.yaw)
        self.queue.append((now + self.latency, pose))
        while self.queue and self.queue[0][0] <= now:
            _, (x, y, yaw) = self.queue.popleft()
            msg = PoseStamped()
            msg.header.frame_id = "world"
            msg.header.stamp = self.node.get_clock().now().to_msg()
            msg.pose.position.x, msg.pose.position.y = x, y
            msg.pose.orientation.z, msg.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            self.pub.publish(msg)


def main(config_path: str) -> int:
    config = json.loads(Path(config_path).read_text())
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    rclpy.init(domain_id=int(config["domain_id"]),
               signal_handler_options=SignalHandlerOptions.NO)
    executor = SingleThreadedExecutor()
    lock = threading.Lock()
    rate = float(config.get("rate", 100.0))
    with open(config["log"], "a", encoding="utf-8") as log:
        robots = []
        for spec in config["robots"]:
            node = rclpy.create_node(f"fake_{spec['name']}")
            executor.add_node(node)
            robots.append(FakeRobot(node, spec, log, lock))
        spinner = threading.Thread(target=lambda: _spin(executor, stop), daemon=True)
        spinner.start()
        Path(config["ready"]).write_text("ready\n")
        period, substeps = 1.0 / rate, 4
        last = time.monotonic()
        next_due = last + period
        while not stop.is_set():
            stop.wait(max(0.0, next_due - time.monotonic()))
            now = time.monotonic()
            for robot in robots:
                for _ in range(substeps):
                    robot.step((now - last) / substeps, now)
                robot.sample(now)
            last = now
            next_due += period
            if next_due < now:
                next_due = now + period
        spinner.join(timeout=5.0)
        state = {r.name: [r.x, r.y, r.yaw] for r in robots}
        Path(config["ready"]).write_text(json.dumps({"final": state}) + "\n")
    executor.shutdown()
    rclpy.shutdown()
    return 0


def _spin(executor, stop: threading.Event) -> None:
    while not stop.is_set() and rclpy.ok():
        executor.spin_once(timeout_sec=0.05)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
