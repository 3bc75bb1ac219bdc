"""``tlfleet ros-mirror``: a running fleet on ROS 2, read-only, for rviz2, Foxglove and Nav2
(docs/hardware.md §The ROS mirror). The module that imports rclpy for it.

It reads what the recorder reads — the frames on ``mocap``, the agents' statuses, the events —
and sends nothing to the fleet. It publishes in the fixed frame ``world``
(:mod:`.ros_messages` builds the messages, the same as ``tlfleet export-mcap`` writes):

* ``<prefix>/robot<id>/pose`` — ``geometry_msgs/msg/PoseStamped``;
* ``<prefix>/robot<id>/odom`` — ``nav_msgs/msg/Odometry`` (velocity from consecutive frames, in
  the body frame ``robot<id>``);
* ``<prefix>/poses`` — ``geometry_msgs/msg/PoseArray`` of every robot, ids ascending;
* ``<prefix>/scene`` — ``visualization_msgs/msg/MarkerArray`` of arena, obstacles and regions,
  transient-local (a viewer that joins later gets it) and re-sent every few seconds;
* ``/diagnostics`` — ``diagnostic_msgs/msg/DiagnosticArray``: each status as it comes, and the
  events (contacts, watchdog stops, halts at level WARN).

Poses go out at most ``rate`` times a second (the newest frame each time), stamped with the
frame's sim time. Best-effort for the poses (sensor data), reliable for the rest.
"""

from __future__ import annotations

import importlib
import logging
import math
import re
import threading
import time
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from rclpy.signals import SignalHandlerOptions
from tlfleet.agent.model import Scenario
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import ProtocolError, decode
from tlfleet.bus.protocol.messages import Event, LtlStatus, MocapFrame, StlStatus
from tlfleet.bus.transport import Transport
from tlfleet.coordinator.report import ros_messages as rm
from tlfleet.coordinator.report.mcap_export import WARN_KINDS

logger = logging.getLogger(__name__)

RELIABLE = QoSProfile(reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE, history=HistoryPolicy.KEEP_LAST,
                      depth=10)
LATCHED = QoSProfile(reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL,
                     history=HistoryPolicy.KEEP_LAST, depth=1)
SCENE_PERIOD = 5.0  # [s] wall between re-sends of the scene


@dataclass(frozen=True)
class MirrorConfig:
    rate: float = 30.0  # [Hz] at most, for the poses
    prefix: str = "/tlfleet"
    domain_id: int | None = None  # None: ROS_DOMAIN_ID of the environment
    exit_on_done: bool = True  # end after the fleet's sim_done


def _message_class(type_text: str) -> Any:
    """The rclpy class of a field type such as ``sequence<geometry_msgs/Pose>`` or
    ``geometry_msgs/Pose[36]``."""
    name = re.sub(r"^sequence<|>$|\[\d*\]$", "", type_text)
    package, short = name.split("/")[0], name.split("/")[-1]
    return getattr(importlib.import_module(f"{package}.msg"), short)


def fill(msg: Any, values: dict[str, Any]) -> Any:
    """Copy the plain values of :mod:`.ros_messages` into the rclpy message ``msg``."""
    types = msg.get_fields_and_field_types()
    for name, value in values.items():
        kind = types[name]
        if isinstance(value, dict):
            fill(getattr(msg, name), value)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            cls = _message_class(kind)
            setattr(msg, name, [fill(cls(), item) for item in value])
        elif kind in ("octet", "byte") and isinstance(value, int):
            setattr(msg, name, bytes([value]))
        else:
            setattr(msg, name, value)
    return msg


class RosMirror:
    """The mirror of one fleet (see the module docstring)."""

    def __init__(self, transport: Transport, scenario: Scenario, config: MirrorConfig,
                 stop: threading.Event):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseArray, PoseStamped
        from nav_msgs.msg import Odometry
        from visualization_msgs.msg import MarkerArray

        self.transport, self.scenario, self.config, self.stop = transport, scenario, config, stop
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=config.domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("tlfleet_mirror", context=self.context)
        p = config.prefix.rstrip("/")
        ids = sorted(scenario.robot_ids)
        self._classes = {"pose": PoseStamped, "odom": Odometry, "array": PoseArray,
                         "scene": MarkerArray, "diag": DiagnosticArray}
        self.pose_pub = {r: self.node.create_publisher(PoseStamped, f"{p}/robot{r}/pose",
                                                       qos_profile_sensor_data) for r in ids}
        self.odom_pub = {r: self.node.create_publisher(Odometry, f"{p}/robot{r}/odom",
                                                       qos_profile_sensor_data) for r in ids}
        self.array_pub = self.node.create_publisher(PoseArray, f"{p}/poses",
                                                    qos_profile_sensor_data)
        self.scene_pub = self.node.create_publisher(MarkerArray, f"{p}/scene", LATCHED)
        self.diag_pub = self.node.create_publisher(DiagnosticArray, "/diagnostics", RELIABLE)
        self._lock = threading.Lock()
        self._frame: MocapFrame | None = None
        self._previous: MocapFrame | None = None
        self._queue: list[tuple[float, dict[str, Any]]] = []  # diagnostics to send
        self.published = {"poses": 0, "diagnostics": 0, "scene": 0}
        self.done = False

    # zenoh threads: store and return
    def _on_frame(self, _key: str, payload: bytes) -> None:
        try:
            frame = decode(MocapFrame, payload)
        except ProtocolError:
            return
        with self._lock:
            if self._frame is None or frame.t > self._frame.t:
                self._frame = frame

    def _on_status(self, _key: str, payload: bytes) -> None:
        status: Any = None
        for cls in (StlStatus, LtlStatus):
            try:
                status = decode(cls, payload)
                break
            except ProtocolError:
                continue
        if status is None:
            return
        values = {f: getattr(status, f) for f in status.__slots__ if f not in ("robot", "t")}
        with self._lock:
            self._queue.append((status.t, rm.diagnostic_status(f"robot{status.robot}", values)))

    def _on_event(self, _key: str, payload: bytes) -> None:
        try:
            event = decode(Event, payload)
        except ProtocolError:
            return
        values = {k: v for k, v in event.data.items() if isinstance(v, int | float | str)}
        with self._lock:
            self._queue.append((event.t, rm.diagnostic_status(
                event.source, values, level=1 if event.kind in WARN_KINDS else 0,
                message=event.kind)))
            if event.kind == "sim_done":
                self.done = True

    def run(self) -> int:
        fleet = self.scenario.fleet
        handles = [self.transport.subscribe(keys.mocap(fleet), self._on_frame),
                   self.transport.subscribe(keys.all_statuses(fleet), self._on_status),
                   self.transport.subscribe(keys.all_events(fleet), self._on_event)]
        period = 1.0 / self.config.rate
        next_scene = 0.0
        last_t = -1.0
        logger.info("ros-mirror: fleet %s on ROS domain %s, poses at most %g Hz", fleet,
                    self.config.domain_id, self.config.rate)
        try:
            while not self.stop.is_set():
                now = time.monotonic()
                if now >= next_scene:
                    self.scene_pub.publish(fill(self._classes["scene"](),
                                                rm.scene_markers(self.scenario)))
                    self.published["scene"] += 1
                    next_scene = now + SCENE_PERIOD
                with self._lock:
                    frame, queue, self._queue = self._frame, self._queue, []
                    done = self.done
                if frame is not None and frame.t > last_t:
                    self._publish_frame(frame)
                    last_t = frame.t
                for t, status in queue:
                    self.diag_pub.publish(fill(self._classes["diag"](),
                                               rm.diagnostic_array(t, [status])))
                    self.published["diagnostics"] += 1
                if done and self.config.exit_on_done:
                    break
                self.stop.wait(max(0.0, period - (time.monotonic() - now)))
        finally:
            for handle in handles:
                handle.close()
            self.node.destroy_node()
            rclpy.shutdown(context=self.context)
        logger.info("ros-mirror: published %s", self.published)
        return 0

    def _publish_frame(self, frame: MocapFrame) -> None:
        previous, self._previous = self._previous, frame
        poses = [(row[1], row[2], row[3]) for row in frame.poses]
        for row in frame.poses:
            robot, p = row[0], (row[1], row[2], row[3])
            if robot not in self.pose_pub:
                continue
            self.pose_pub[robot].publish(fill(self._classes["pose"](),
                                              rm.pose_stamped(frame.t, *p)))
            v = (0.0, 0.0, 0.0)
            before = previous.pose(robot) if previous is not None else None
            if before is not None and frame.t > previous.t:
                dt = frame.t - previous.t
                dth = math.atan2(math.sin(p[2] - before[2]), math.cos(p[2] - before[2]))
                v = ((p[0] - before[0]) / dt, (p[1] - before[1]) / dt, dth / dt)
            self.odom_pub[robot].publish(fill(self._classes["odom"](),
                                              rm.odometry(frame.t, robot, p, v)))
        self.array_pub.publish(fill(self._classes["array"](), rm.pose_array(frame.t, poses)))
        self.published["poses"] += 1
