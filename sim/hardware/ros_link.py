"""The hardware bridge's ROS 2 side (docs/hardware.md): the only bridge module that imports
rclpy (tests/project/test_layering.py).

:class:`RosLink` holds one rclpy node in its own context, and no executor. Per robot of the lab
file it subscribes to the rigid body's pose topic (best-effort: matches best-effort and reliable
publishers, as mocap drivers such as vrpn_mocap publish sensor data) and publishes the velocity
command (reliable, volatile: matches reliable and best-effort subscribers; a best-effort
publisher never matches the reliable subscriptions of ros2_controllers).

**Poses are polled, not called back.** The frames sample and hold each body's newest pose, so
the bridge's loop calls :meth:`RosLink.poll` just before it reads the poses: it takes every
message that came since, serialized, and reads only the newest usable one per body — its seven
numbers straight from the CDR bytes (:mod:`tlfleet.sim.hardware.cdr`; rclpy's
``deserialize_message`` for an encoding that module does not read). An executor thread instead
woke for every pose and ran ≈ 0.1–0.2 ms of Python on it (rclpy's ``SingleThreadedExecutor``);
the poll adds no delay to the frames (it runs right before a frame is built).

**Commands reuse one message per robot**: :meth:`RosLink.send` sets its fields and publishes
(rclpy copies it into DDS at ``publish``), the stamp from the system clock, which is what the
node's ROS clock reads without simulated time.

rclpy's own signal handlers are off (``SignalHandlerOptions.NO``): by default they shut the
context at SIGTERM, before the bridge could send its final zero commands; the bridge's own
handlers stop it, it sends the zeros, waits for the robots to acknowledge them, and only then
closes this link.

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
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions
from tlfleet.agent.scenario.lab import Lab
from tlfleet.agent.scenario.rep103 import yaw_of_quaternion
from tlfleet.sim.hardware.cdr import pose_fields

logger = logging.getLogger(__name__)

MOCAP_QOS = QoSProfile(reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE, history=HistoryPolicy.KEEP_LAST,
                       depth=5)
CMD_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                     history=HistoryPolicy.KEEP_LAST, depth=10)

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


def planar_pose_of(type_name: str, cls: Any, data: bytes) -> tuple[float, float, float]:
    """``(x, y, yaw)`` [m, m, rad] of a serialized pose message: read from the CDR bytes, or
    deserialized by rclpy when :func:`tlfleet.sim.hardware.cdr.pose_fields` cannot read them.
    ``ValueError`` for an unusable pose (a zero quaternion...)."""
    fields = pose_fields(type_name, data)
    if fields is None:
        return planar_pose(type_name, deserialize_message(data, cls))
    x, y, _z, qx, qy, qz, qw = fields
    return x, y, yaw_of_quaternion(qx, qy, qz, qw)


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
        # no executor serves this node, so it offers no parameter services
        self.node = rclpy.create_node(lab.node_name, context=self.context,
                                      start_parameter_services=False)
        self._mocap: list[_Mocap] = []
        self._twist: dict[int, tuple[Any, Any, bool]] = {}  # robot -> (message, body, stamped)
        self._publishers: dict[int, Any] = {}
        self._polling = threading.Lock()
        self.poses_received = 0
        self.bad_poses = 0
        for robot in lab.robots:
            cls = message_class(robot.mocap_type)
            subscription = self.node.create_subscription(cls, robot.mocap_topic, _unused,
                                                         MOCAP_QOS, raw=True)
            self._mocap.append(_Mocap(robot.id, robot.mocap_topic, robot.mocap_type, cls,
                                      subscription))
            cmd_cls = message_class(robot.cmd_type)
            stamped = robot.cmd_type.endswith("TwistStamped")
            msg = cmd_cls()
            if stamped:
                msg.header.frame_id = robot.frame_id
            self._twist[robot.id] = (msg, msg.twist if stamped else msg, stamped)
            self._publishers[robot.id] = self.node.create_publisher(cmd_cls, robot.cmd_topic,
                                                                    CMD_QOS)

    def poll(self) -> int:
        """Take every pose that came since the last call; hand each body's newest usable one
        to ``on_pose``. Returns how many poses were taken. Called by the bridge's loop before
        it reads the poses (a second caller meanwhile returns at once)."""
        if not self._polling.acquire(blocking=False):
            return 0
        taken = 0
        try:
            for body in self._mocap:
                batch = []
                handle = body.subscription.handle
                with handle:
                    while (got := handle.take_message(body.cls, True)) is not None:
                        batch.append(got[0])
                if batch:
                    taken += len(batch)
                    self._newest(body, batch)
        finally:
            self._polling.release()
        self.poses_received += taken
        return taken

    def _newest(self, body: _Mocap, batch: list[bytes]) -> None:
        """The newest usable pose of ``batch`` (serialized, oldest first) to ``on_pose``; an
        unusable one (a zero quaternion, NaN) is counted and the one before it tried."""
        for data in reversed(batch):
            try:
                x, y, yaw = planar_pose_of(body.type_name, body.cls, data)
            except Exception as exc:  # a zero quaternion, bytes rclpy cannot deserialize...
                self.bad_poses += 1
                if self.bad_poses == 1:
                    logger.warning("robot %d: unusable pose on %s: %s", body.robot, body.topic,
                                   exc)
                continue
            try:
                self._on_pose(body.robot, x, y, yaw)
            except Exception:  # one pose must never stop the loop
                logger.exception("robot %d: handling a pose failed", body.robot)
            return

    def send(self, robot: int, twist: tuple[float, float, float]) -> None:
        """Publish ``(linear.x, linear.y, angular.z)`` [m/s, m/s, rad/s] on ``robot``'s command
        topic (a TwistStamped stamped now or zero, after the lab's ``cmd_stamp``). The sends
        to one robot must not overlap (the bridge sends under its world's lock): they share
        one message."""
        msg, body, stamped = self._twist[robot]
        body.linear.x, body.linear.y, body.angular.z = (float(v) for v in twist)
        if stamped and self.lab.cmd_stamp == "now":
            stamp = msg.header.stamp
            stamp.sec, stamp.nanosec = divmod(time.time_ns(), 1_000_000_000)
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
        """Shut the node and the context down (after the final zeros)."""
        with self._polling:
            try:
                self.node.destroy_node()
            except Exception:
                logger.exception("shutting the ROS node down failed")
            finally:
                if self.context.ok():
                    rclpy.shutdown(context=self.context)


@dataclass(frozen=True)
class _Mocap:
    """One rigid body's pose subscription (raw: its messages stay serialized until used)."""

    robot: int
    topic: str
    type_name: str
    cls: Any
    subscription: Any


def _unused(_msg: Any) -> None:
    """The subscriptions' callback: no executor calls it (:meth:`RosLink.poll` takes)."""


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
