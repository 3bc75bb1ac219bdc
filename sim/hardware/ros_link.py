"""The hardware bridge's ROS 2 side (docs/hardware.md): the only bridge module that imports
rclpy (tests/project/test_layering.py).

:class:`RosLink` holds one rclpy node in its own context, spun by a ``SingleThreadedExecutor`` on
a daemon thread. Per robot of the lab file it subscribes to the rigid body's pose topic
(best-effort: matches best-effort and reliable publishers, as mocap drivers such as vrpn_mocap
publish sensor data) and publishes the velocity command (reliable, volatile: matches reliable and
best-effort subscribers; a best-effort publisher never matches the reliable subscriptions of
ros2_controllers). rclpy's own signal handlers are off (``SignalHandlerOptions.NO``): by default
they shut the context at SIGTERM, before the bridge could send its final zero commands; the
bridge's own handlers stop it, it sends the zeros, waits for the robots to acknowledge them, and
only then closes this link.

:func:`graph_report` is ``tlfleet hw --check``: what the lab's topics look like on the ROS graph.
"""

from __future__ import annotations

import importlib
import logging
import os
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from tlfleet.agent.scenario.lab import Lab, LabRobot
from tlfleet.agent.scenario.rep103 import yaw_of_quaternion

logger = logging.getLogger(__name__)

MOCAP_QOS = QoSProfile(reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE, history=HistoryPolicy.KEEP_LAST,
                       depth=5)
CMD_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                     history=HistoryPolicy.KEEP_LAST, depth=10)

SPIN_SLICE = 0.1  # [s] longest wait of the executor before it looks at the closing flag

PoseCallback = Callable[[int, float, float, float], None]


def message_class(type_name: str) -> Any:
    """The rclpy message class of ``pkg/msg/Name``."""
    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def planar_pose(type_name: str, msg: Any) -> tuple[float, float, float]:
    """``(x, y, yaw)`` [m, m, rad] of a pose message of one of the lab's mocap types."""
    if type_name.endswith("/TransformStamped"):
        p, q = msg.transform.translation, msg.transform.rotation
    elif type_name.endswith("/PoseStamped"):
        p, q = msg.pose.position, msg.pose.orientation
    else:  # PoseWithCovarianceStamped, Odometry
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
    return float(p.x), float(p.y), yaw_of_quaternion(q.x, q.y, q.z, q.w)


def apply_ros_environment(lab: Lab) -> None:
    """Put this process on the lab's ROS graph (before rclpy initialises)."""
    for name, value in lab.ros_environment().items():
        os.environ[name] = value


class RosLink:
    """The lab's topics in one node (see the module docstring)."""

    def __init__(self, lab: Lab, on_pose: PoseCallback):
        self.lab = lab
        self._on_pose = on_pose
        apply_ros_environment(lab)
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=lab.domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(lab.node_name, context=self.context)
        self._twist: dict[int, tuple[Any, bool, str]] = {}
        self._publishers: dict[int, Any] = {}
        self.poses_received = 0
        self.bad_poses = 0
        for robot in lab.robots:
            self._subscribe(robot)
            cls = message_class(robot.cmd_type)
            stamped = robot.cmd_type.endswith("TwistStamped")
            self._twist[robot.id] = (cls, stamped, robot.frame_id)
            self._publishers[robot.id] = self.node.create_publisher(cls, robot.cmd_topic, CMD_QOS)
        self._closing = threading.Event()
        self.executor = _executor(self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name="ros-executor", daemon=True)
        self._thread.start()

    def _subscribe(self, robot: LabRobot) -> None:
        type_name, robot_id = robot.mocap_type, robot.id

        def on_message(msg: Any) -> None:
            try:
                x, y, yaw = planar_pose(type_name, msg)
            except (ValueError, AttributeError) as exc:  # a zero quaternion, NaN...
                self.bad_poses += 1
                if self.bad_poses == 1:
                    logger.warning("robot %d: unusable pose on %s: %s", robot_id,
                                   robot.mocap_topic, exc)
                return
            self.poses_received += 1
            try:
                self._on_pose(robot_id, x, y, yaw)
            except Exception:  # never let one pose stop the executor
                logger.exception("robot %d: handling a pose failed", robot_id)

        self.node.create_subscription(message_class(type_name), robot.mocap_topic, on_message,
                                      MOCAP_QOS)

    def _spin(self) -> None:
        while not self._closing.is_set() and self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=SPIN_SLICE)
            except Exception:  # the context shut down under it: the link is closing
                if self._closing.is_set() or not self.context.ok():
                    return
                logger.exception("the ROS executor failed; going on")

    def send(self, robot: int, twist: tuple[float, float, float]) -> None:
        """Publish ``(linear.x, linear.y, angular.z)`` [m/s, m/s, rad/s] on ``robot``'s command
        topic (a TwistStamped stamped now or zero, after the lab's ``cmd_stamp``)."""
        cls, stamped, frame_id = self._twist[robot]
        msg = cls()
        body = msg.twist if stamped else msg
        body.linear.x, body.linear.y, body.angular.z = (float(v) for v in twist)
        if stamped:
            msg.header.frame_id = frame_id
            if self.lab.cmd_stamp == "now":
                msg.header.stamp = self.node.get_clock().now().to_msg()
        self._publishers[robot].publish(msg)

    def wait_acked(self, timeout: float) -> bool:
        """Wait (at most ``timeout`` [s] wall in all) until every robot's subscribers have
        acknowledged everything sent; False when one has not."""
        deadline = time.monotonic() + timeout
        ok = True
        for publisher in self._publishers.values():
            left = max(0.0, deadline - time.monotonic())
            ok = publisher.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9))) and ok
        return ok

    def subscriber_counts(self) -> dict[int, int]:
        return {r: p.get_subscription_count() for r, p in self._publishers.items()}

    def close(self) -> None:
        """Stop the executor's thread, then shut the node and the context down (after the final
        zeros)."""
        self._closing.set()
        self._thread.join(timeout=2.0 + SPIN_SLICE)
        try:
            self.executor.shutdown(timeout_sec=1.0)
            self.node.destroy_node()
        except Exception:
            logger.exception("shutting the ROS node down failed")
        finally:
            if self.context.ok():
                rclpy.shutdown(context=self.context)


def _executor(context: Any) -> Any:
    # rclpy.experimental.EventsExecutor would halve the executor's CPU, but in its own context
    # (Kilted wheels) it delivered no pose and spun a core; the plain executor it is
    return SingleThreadedExecutor(context=context)


# --------------------------------------------------------------------------- tlfleet hw --check


@dataclass(frozen=True)
class Endpoint:
    """One publisher or subscription seen on the graph."""

    node: str
    type: str
    reliability: str
    durability: str  # (DDS discovery does not carry the history depth)


@dataclass(frozen=True)
class TopicReport:
    robot: int
    role: str  # "mocap" (the bridge reads it) | "cmd" (the bridge writes it)
    topic: str
    expected_type: str
    endpoints: tuple[Endpoint, ...]  # mocap: its publishers; cmd: its subscribers
    problems: tuple[str, ...]


def graph_report(lab: Lab, wait: float = 2.0) -> list[TopicReport]:
    """What the ROS graph of ``lab`` shows after ``wait`` [s] of discovery: for each robot the
    publishers of its mocap topic and the subscribers of its command topic, with their types and
    QoS, and what would keep the bridge from working (nothing there, another type, a QoS that
    does not match the bridge's: best-effort volatile reader, reliable volatile writer)."""
    apply_ros_environment(lab)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=lab.domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = rclpy.create_node(f"{lab.node_name}_check", context=context)
        time.sleep(wait)
        out = []
        for robot in lab.robots:
            for role, topic, expected, infos in (
                    ("mocap", robot.mocap_topic, robot.mocap_type,
                     node.get_publishers_info_by_topic(robot.mocap_topic)),
                    ("cmd", robot.cmd_topic, robot.cmd_type,
                     node.get_subscriptions_info_by_topic(robot.cmd_topic))):
                endpoints = tuple(_endpoint(info) for info in infos)
                out.append(TopicReport(robot.id, role, topic, expected, endpoints,
                                       tuple(_problems(role, expected, endpoints))))
        node.destroy_node()
        return out
    finally:
        rclpy.shutdown(context=context)


def _endpoint(info: Any) -> Endpoint:
    qos = info.qos_profile
    return Endpoint(node=f"{info.node_namespace.rstrip('/')}/{info.node_name}",
                    type=info.topic_type, reliability=_policy(qos.reliability),
                    durability=_policy(qos.durability))


def _policy(value: Any) -> str:
    return getattr(value, "name", str(value)).lower()


def _problems(role: str, expected: str, endpoints: tuple[Endpoint, ...]) -> list[str]:
    if not endpoints:
        return [f"no {'publisher' if role == 'mocap' else 'subscriber'}"]
    problems = []
    types = sorted({e.type for e in endpoints} - {expected})
    if types:
        problems.append(f"type {', '.join(types)} (the lab says {expected})")
    if role == "cmd":
        late = [e.node for e in endpoints if e.durability == "transient_local"]
        if late:
            problems.append(f"transient_local subscriber(s) {', '.join(late)} never match the "
                            f"bridge's volatile publisher")
    return problems


def timeouts(lab: Lab) -> Mapping[int, float | None]:
    """The robots' own command timeouts as the lab file records them (what stops a robot when
    the bridge crashes)."""
    return {r.id: r.robot_timeout for r in lab.robots}
