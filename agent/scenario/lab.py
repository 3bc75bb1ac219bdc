"""Lab files: the hardware a scenario runs on (docs/hardware.md).

The scenario is the task; the lab is the hardware: which ROS 2 domain the robots and the motion
capture live on, which topic carries each robot's rigid-body pose and which one takes its velocity
command, and the bridge's safety settings. ``tlfleet hw SCENARIO --lab LAB.toml`` and ``tlfleet
run SCENARIO --hardware LAB.toml`` read it with :func:`load_lab` and check it against the scenario
with :func:`check_lab`. Errors are :class:`~tlfleet.bus.errors.ScenarioError` s naming the lab
file, the field path (``robots[1].cmd.topic``) and what was expected, as for scenario files;
unknown keys are errors.

File layout (docs/hardware.md documents every key)::

    [ros]      domain_id, discovery_range, static_peers, world_frame, cmd_stamp, node_name
    [mocap]    lost_after
    [safety]   geofence_margin, stop_repeats, stop_ack_timeout
    [[robots]] id, mocap = {topic, type}, cmd = {topic, type, frame_id, repeat_hz},
               pose_offset = [dx, dy, dψ], robot_timeout

Pure: no ROS import; the types are checked by name.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tlfleet.agent.model import Scenario
from tlfleet.agent.scenario import validation
from tlfleet.agent.scenario.loader import _Table
from tlfleet.bus.errors import ScenarioError

#: pose messages the bridge reads a rigid body from (the first is vrpn_mocap's and the default)
MOCAP_TYPES = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped",
               "geometry_msgs/msg/TransformStamped", "nav_msgs/msg/Odometry")
#: velocity commands the bridge sends (Jazzy and later bases take TwistStamped on cmd_vel)
CMD_TYPES = ("geometry_msgs/msg/TwistStamped", "geometry_msgs/msg/Twist")
#: ROS_AUTOMATIC_DISCOVERY_RANGE values (ROS 2 Iron and later)
DISCOVERY_RANGES = ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT")
CMD_STAMPS = ("now", "zero")
MAX_DOMAIN_ID = 232  # ROS 2's limit for Fast DDS / Cyclone port mapping on Linux
_TOPIC = re.compile(r"/?[A-Za-z_~][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*\Z")
_NODE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_FRAME = re.compile(r"[A-Za-z_][A-Za-z0-9_/]*\Z")


@dataclass(frozen=True)
class LabRobot:
    """One robot's hardware: its rigid body on the mocap and its velocity-command topic."""

    id: int  # the scenario's robot id; its kind (unicycle / omni) comes from the scenario
    mocap_topic: str
    mocap_type: str
    cmd_topic: str
    cmd_type: str
    frame_id: str = "base_link"  # header.frame_id of a TwistStamped (REP 105)
    repeat_hz: float = 20.0  # [Hz] keep-alive: the newest fresh command re-sent this often
    pose_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [m, m, rad] robot in body frame
    robot_timeout: float | None = None  # [s] the robot's own command timeout (what covers a
    #                                     crash of the bridge), as the lab knows it


@dataclass(frozen=True)
class Lab:
    """A whole lab file (see the module docstring)."""

    robots: tuple[LabRobot, ...]
    domain_id: int = 0
    discovery_range: str = "SUBNET"
    static_peers: tuple[str, ...] = ()
    world_frame: str = "world"
    cmd_stamp: str = "now"  # "now": the bridge's clock; "zero": the robot stamps it on receipt
    node_name: str = "tlfleet_hw"
    lost_after: float = 0.1  # [s] a rigid body without a pose this long → tracking lost
    geofence_margin: float = 0.2  # [m] beyond the arena's walls → geofence stop
    stop_repeats: int = 3  # zero commands sent to each robot at a stop
    stop_ack_timeout: float = 0.5  # [s] wall, waiting for the robots to acknowledge the zeros
    source: Path | None = None

    def robot(self, robot_id: int) -> LabRobot:
        for robot in self.robots:
            if robot.id == robot_id:
                return robot
        raise KeyError(robot_id)

    def ros_environment(self) -> dict[str, str]:
        """The environment variables that put a ROS 2 process on this lab's graph."""
        env = {"ROS_DOMAIN_ID": str(self.domain_id)}
        if self.discovery_range != "SYSTEM_DEFAULT":
            env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = self.discovery_range
        if self.static_peers:
            env["ROS_STATIC_PEERS"] = ";".join(self.static_peers)
        return env


def load_lab(path: str | Path) -> Lab:
    """Read and validate a lab file; ``ScenarioError`` (file, field, reason) on any problem."""
    path = Path(path)
    data = validation.parse_toml(validation.read_text(path), str(path))
    return parse_lab(data, source=str(path))


def parse_lab(data: dict[str, Any], source: str = "<lab>") -> Lab:
    """Validate a decoded lab TOML table and build the :class:`Lab`."""
    top = _Table(data, "", source)
    ros = top.table("ros", required=False) or _Table({}, "ros", source)
    domain_id = ros.integer("domain_id", default=0)
    if not 0 <= domain_id <= MAX_DOMAIN_ID:
        ros.fail("domain_id", f"expected an integer in [0, {MAX_DOMAIN_ID}], got {domain_id}")
    discovery = ros.string("discovery_range", default="SUBNET")
    if discovery not in DISCOVERY_RANGES:
        ros.fail("discovery_range", f"expected one of {', '.join(map(repr, DISCOVERY_RANGES))}, "
                                    f"got {discovery!r}")
    peers = ros.list_of("static_peers", str, "string", default=[])
    for k, peer in enumerate(peers):
        if not peer or any(c.isspace() or c == ";" for c in peer):
            ros.fail(f"static_peers[{k}]", f"expected a host name or address, got {peer!r}")
    world_frame = _frame(ros, "world_frame", "world")
    cmd_stamp = ros.string("cmd_stamp", default="now")
    if cmd_stamp not in CMD_STAMPS:
        ros.fail("cmd_stamp", f"expected 'now' (the bridge's clock; needs clocks "
                              f"synchronised with the robots) or 'zero' (the robot stamps it), "
                              f"got {cmd_stamp!r}")
    node_name = ros.string("node_name", default="tlfleet_hw")
    if not _NODE.match(node_name):
        ros.fail("node_name", f"expected a ROS node name (letters, digits, _), got {node_name!r}")
    ros.finish()

    mocap = top.table("mocap", required=False) or _Table({}, "mocap", source)
    lost_after = mocap.number("lost_after", default=0.1, positive=True)
    mocap.finish()

    safety = top.table("safety", required=False) or _Table({}, "safety", source)
    margin = safety.number("geofence_margin", default=0.2)
    if margin < 0.0:
        safety.fail("geofence_margin", f"expected a number ≥ 0 [m], got {margin}")
    repeats = safety.integer("stop_repeats", default=3)
    if not 1 <= repeats <= 100:
        safety.fail("stop_repeats", f"expected an integer in [1, 100], got {repeats}")
    ack = safety.number("stop_ack_timeout", default=0.5, positive=True)
    safety.finish()

    robots = tuple(_robot(t) for t in top.array_of_tables("robots"))
    if not robots:
        top.fail("robots", "expected at least one [[robots]] table")
    for field, what in (("id", "robot id"), ("mocap_topic", "mocap topic"),
                        ("cmd_topic", "command topic")):
        seen: dict[Any, int] = {}
        for index, robot in enumerate(robots):
            value = getattr(robot, field)
            if value in seen:
                suffix = {"id": "id", "mocap_topic": "mocap.topic", "cmd_topic": "cmd.topic"}
                raise ScenarioError(source, f"robots[{index}].{suffix[field]}",
                                    f"duplicate {what} {value!r} (first at robots[{seen[value]}])")
            seen[value] = index
    top.finish()
    return Lab(robots=robots, domain_id=domain_id, discovery_range=discovery,
               static_peers=tuple(peers), world_frame=world_frame, cmd_stamp=cmd_stamp,
               node_name=node_name, lost_after=lost_after, geofence_margin=margin,
               stop_repeats=repeats, stop_ack_timeout=ack,
               source=Path(source) if source and not source.startswith("<") else None)


def check_lab(lab: Lab, scenario: Scenario) -> None:
    """The lab must drive exactly the scenario's robots, and each robot's keep-alive must come
    faster than its own command timeout; ``ScenarioError`` naming the lab file otherwise."""
    source = str(lab.source) if lab.source else "<lab>"
    ids = {r.id for r in scenario.robots}
    for index, robot in enumerate(lab.robots):
        if robot.id not in ids:
            raise ScenarioError(source, f"robots[{index}].id",
                                f"robot {robot.id} is not in scenario {scenario.name!r} "
                                f"(its robots: {', '.join(map(str, sorted(ids)))})")
    for index, robot in enumerate(lab.robots):
        if robot.robot_timeout is not None and 1.0 / robot.repeat_hz >= robot.robot_timeout:
            raise ScenarioError(source, f"robots[{index}].cmd.repeat_hz",
                                f"{robot.repeat_hz:g} Hz re-sends a command every "
                                f"{1.0 / robot.repeat_hz:g} s, not within the robot's own "
                                f"timeout robot_timeout = {robot.robot_timeout:g} s: it would "
                                f"stop between two re-sends")
    missing = sorted(ids - {r.id for r in lab.robots})
    if missing:
        listed = ", ".join(map(str, missing))
        raise ScenarioError(source, "robots",
                            f"scenario {scenario.name!r} has robot(s) {listed} without a "
                            f"[[robots]] entry (mocap and cmd topics)")


def _robot(table: _Table) -> LabRobot:
    robot_id = table.integer("id")
    if robot_id < 0:
        table.fail("id", f"expected a robot id ≥ 0, got {robot_id}")
    mocap = table.table("mocap")
    mocap_topic = _topic(mocap, "topic")
    mocap_type = _type(mocap, "type", MOCAP_TYPES, MOCAP_TYPES[0])
    mocap.finish()
    cmd = table.table("cmd")
    cmd_topic = _topic(cmd, "topic")
    cmd_type = _type(cmd, "type", CMD_TYPES, CMD_TYPES[0])
    frame_id = _frame(cmd, "frame_id", "base_link")
    repeat_hz = cmd.number("repeat_hz", default=20.0, positive=True)
    if repeat_hz > 1000.0:
        cmd.fail("repeat_hz", f"expected at most 1000 Hz, got {repeat_hz}")
    cmd.finish()
    offset = table.vector("pose_offset", 3) if table.has("pose_offset") else (0.0, 0.0, 0.0)
    timeout = table.number("robot_timeout", default=None, positive=True)
    table.finish()
    return LabRobot(id=robot_id, mocap_topic=mocap_topic, mocap_type=mocap_type,
                    cmd_topic=cmd_topic, cmd_type=cmd_type, frame_id=frame_id,
                    repeat_hz=repeat_hz, pose_offset=offset, robot_timeout=timeout)


def _topic(table: _Table, key: str) -> str:
    topic = table.string(key)
    if not _TOPIC.match(topic) or "__" in topic:
        table.fail(key, f"expected a ROS topic name such as '/vrpn_mocap/tb1/pose' (letters, "
                        f"digits and _ between single slashes), got {topic!r}")
    return topic


def _type(table: _Table, key: str, options: tuple[str, ...], default: str) -> str:
    name = table.string(key, default=default)
    canonical = name if "/msg/" in name else name.replace("/", "/msg/", 1)
    if canonical not in options:
        table.fail(key, f"expected one of {', '.join(map(repr, options))}, got {name!r}")
    return canonical


def _frame(table: _Table, key: str, default: str) -> str:
    frame = table.string(key, default=default)
    if not _FRAME.match(frame):
        table.fail(key, f"expected a tf frame name such as {default!r}, got {frame!r}")
    return frame
