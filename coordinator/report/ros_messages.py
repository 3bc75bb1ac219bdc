"""A run in ROS 2 messages, without ROS (docs/hardware.md §MCAP and §The ROS mirror).

Two things, both pure Python:

* the **message definitions** (``ros2msg`` text, as rosbag2 writes them into an MCAP schema: the
  type's fields, then each type it uses after a ``MSG: pkg/Type`` line) of the few standard types
  tlfleet publishes — ``geometry_msgs`` PoseStamped, PoseArray, TwistStamped,
  ``nav_msgs/Odometry``, ``visualization_msgs/MarkerArray``, ``diagnostic_msgs/DiagnosticArray``;
  their fields are those of ROS 2 Jazzy/Kilted (a test compares them with the wheels' ``.msg``
  files);
* the **messages** of a fleet, as plain dicts with those fields: a robot's pose, the fleet's
  ``PoseArray``, a velocity, a status as a ``DiagnosticStatus``, the regions and obstacles as
  markers. ``tlfleet export-mcap`` encodes them to CDR (:mod:`.mcap_export`); ``tlfleet
  ros-mirror`` copies them into rclpy messages (:mod:`.ros_mirror`): one translation for both.

Conventions (REP 103): the fixed frame is ``world`` (the mocap's), Z up, metres, radians; a pose's
heading θ becomes the quaternion of a rotation by θ about Z.
"""

from __future__ import annotations

import math
from typing import Any

from tlfleet.agent.model import DiscObstacle, RectObstacle, Scenario
from tlfleet.agent.scenario.rep103 import quaternion_of_yaw

WORLD = "world"

_SEP = "=" * 80

_BASE = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec",
    "builtin_interfaces/Duration": "int32 sec\nuint32 nanosec",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "std_msgs/ColorRGBA": "float32 r\nfloat32 g\nfloat32 b\nfloat32 a",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation",
    "geometry_msgs/Twist": "Vector3  linear\nVector3  angular",
    "geometry_msgs/PoseWithCovariance": "Pose pose\nfloat64[36] covariance",
    "geometry_msgs/TwistWithCovariance": "Twist twist\nfloat64[36] covariance",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\nPose pose",
    "geometry_msgs/PoseArray": "std_msgs/Header header\nPose[] poses",
    "geometry_msgs/TwistStamped": "std_msgs/Header header\nTwist twist",
    "nav_msgs/Odometry": ("std_msgs/Header header\nstring child_frame_id\n"
                          "geometry_msgs/PoseWithCovariance pose\n"
                          "geometry_msgs/TwistWithCovariance twist"),
    "sensor_msgs/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data",
    "visualization_msgs/UVCoordinate": "float32 u\nfloat32 v",
    "visualization_msgs/MeshFile": "string filename\nuint8[] data",
    "visualization_msgs/Marker": (
        "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\n"
        "int32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\n"
        "int32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\n"
        "int32 ARROW_STRIP=12\nint32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\n"
        "std_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\n"
        "geometry_msgs/Pose pose\ngeometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\n"
        "builtin_interfaces/Duration lifetime\nbool frame_locked\ngeometry_msgs/Point[] points\n"
        "std_msgs/ColorRGBA[] colors\nstring texture_resource\n"
        "sensor_msgs/CompressedImage texture\nUVCoordinate[] uv_coordinates\nstring text\n"
        "string mesh_resource\nMeshFile mesh_file\nbool mesh_use_embedded_materials"),
    "visualization_msgs/MarkerArray": "Marker[] markers",
    "diagnostic_msgs/KeyValue": "string key\nstring value",
    "diagnostic_msgs/DiagnosticStatus": (
        "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\n"
        "string message\nstring hardware_id\nKeyValue[] values"),
    "diagnostic_msgs/DiagnosticArray": "std_msgs/Header header\nDiagnosticStatus[] status",
}

#: the types tlfleet writes, ``pkg/msg/Name``
TYPES = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseArray",
         "geometry_msgs/msg/TwistStamped", "nav_msgs/msg/Odometry",
         "visualization_msgs/msg/MarkerArray", "diagnostic_msgs/msg/DiagnosticArray")


def _fields(name: str) -> list[tuple[str, str]]:
    """``(type, field)`` of ``pkg/Name``'s fields, the types made ``pkg/Name`` (constants out)."""
    package = name.split("/")[0]
    out = []
    for line in _BASE[name].splitlines():
        kind, field = line.split()[:2]
        if "=" in field:
            continue
        base = kind.split("[")[0]
        if base in _PRIMITIVES:
            continue
        out.append((base if "/" in base else f"{package}/{base}", field))
    return out


_PRIMITIVES = frozenset({"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16",
                         "uint16", "int32", "uint32", "int64", "uint64", "string", "wstring"})


def definition(type_name: str) -> str:
    """The ``ros2msg`` schema text of ``pkg/msg/Name``: its fields, then every type it uses
    (depth first, each once) after a separator and ``MSG: pkg/Type``, as rosbag2 writes it."""
    name = type_name.replace("/msg/", "/")
    order: list[str] = []

    def visit(current: str) -> None:
        for sub, _ in _fields(current):
            if sub not in order and sub != name:
                order.append(sub)
                visit(sub)

    visit(name)
    parts = [_BASE[name]]
    for sub in order:
        parts.append(f"{_SEP}\nMSG: {sub}\n{_BASE[sub]}")
    return "\n".join(parts) + "\n"


# --------------------------------------------------------------------------- messages


def stamp(t: float) -> dict[str, int]:
    """``builtin_interfaces/Time`` of ``t`` [s] (sim time since the mission's start)."""
    ns = max(0, round(t * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def header(t: float, frame: str = WORLD) -> dict[str, Any]:
    return {"stamp": stamp(t), "frame_id": frame}


def pose(x: float, y: float, theta: float) -> dict[str, Any]:
    qx, qy, qz, qw = quaternion_of_yaw(theta)
    return {"position": {"x": float(x), "y": float(y), "z": 0.0},
            "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}


def pose_stamped(t: float, x: float, y: float, theta: float) -> dict[str, Any]:
    return {"header": header(t), "pose": pose(x, y, theta)}


def pose_array(t: float, poses: list[tuple[float, float, float]]) -> dict[str, Any]:
    return {"header": header(t), "poses": [pose(*p) for p in poses]}


def twist(vx: float, vy: float, omega: float) -> dict[str, Any]:
    return {"linear": {"x": float(vx), "y": float(vy), "z": 0.0},
            "angular": {"x": 0.0, "y": 0.0, "z": float(omega)}}


def twist_stamped(t: float, vx: float, vy: float, omega: float,
                  frame: str = WORLD) -> dict[str, Any]:
    return {"header": header(t, frame), "twist": twist(vx, vy, omega)}


def odometry(t: float, robot: int, p: tuple[float, float, float],
             v: tuple[float, float, float]) -> dict[str, Any]:
    """``nav_msgs/Odometry`` of robot ``robot``: pose in ``world``, velocity in the robot's body
    frame ``robot<id>`` (REP 105: the twist is in ``child_frame_id``)."""
    c, s = math.cos(p[2]), math.sin(p[2])
    vb = (c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2])
    zero = [0.0] * 36
    return {"header": header(t), "child_frame_id": f"robot{robot}",
            "pose": {"pose": pose(*p), "covariance": zero},
            "twist": {"twist": twist(*vb), "covariance": zero}}


def diagnostic_array(t: float, statuses: list[dict[str, Any]]) -> dict[str, Any]:
    return {"header": header(t), "status": statuses}


def diagnostic_status(name: str, values: dict[str, Any], level: int = 0,
                      message: str = "") -> dict[str, Any]:
    """A ``DiagnosticStatus`` whose key-values are ``values`` as text (level 0 OK, 1 WARN,
    2 ERROR)."""
    return {"level": level, "name": name, "message": message,
            "hardware_id": name, "values": [{"key": str(k), "value": _text(v)}
                                            for k, v in values.items()]}


def _text(value: Any) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else format(value, ".6g")
    return str(value)


_EMPTY_IMAGE = {"header": header(0.0, ""), "format": "", "data": []}


def marker(marker_id: int, ns: str, kind: int, p: dict[str, Any],
           scale: tuple[float, float, float], color: tuple[float, float, float, float],
           text: str = "", points: list[dict[str, float]] | None = None) -> dict[str, Any]:
    return {"header": header(0.0), "ns": ns, "id": marker_id, "type": kind, "action": 0,
            "pose": p, "scale": dict(zip("xyz", scale, strict=True)),
            "color": dict(zip("rgba", color, strict=True)),
            "lifetime": {"sec": 0, "nanosec": 0}, "frame_locked": False,
            "points": points or [], "colors": [], "texture_resource": "",
            "texture": _EMPTY_IMAGE, "uv_coordinates": [], "text": text, "mesh_resource": "",
            "mesh_file": {"filename": "", "data": []}, "mesh_use_embedded_materials": False}


CUBE, SPHERE, CYLINDER, LINE_STRIP, TEXT = 1, 2, 3, 4, 9


def scene_markers(scenario: Scenario) -> dict[str, Any]:
    """The scenario's arena (outline), obstacles, regions (discs with their names) and STL
    goals (each predicate ``dist(p_i, [x, y]) <= c`` of a sub-task: a disc of radius c labelled
    with the robot and the window, as the report's figures mark them) as a ``MarkerArray`` in
    ``world``."""
    a = scenario.arena
    markers = []
    corners = [(a.xmin, a.ymin), (a.xmax, a.ymin), (a.xmax, a.ymax), (a.xmin, a.ymax),
               (a.xmin, a.ymin)]
    markers.append(marker(0, "arena", LINE_STRIP, pose(0, 0, 0), (0.03, 0.0, 0.0),
                          (0.6, 0.6, 0.6, 1.0),
                          points=[{"x": x, "y": y, "z": 0.0} for x, y in corners]))
    for k, obstacle in enumerate(a.obstacles):
        if isinstance(obstacle, RectObstacle):
            cx, cy = (obstacle.xmin + obstacle.xmax) / 2, (obstacle.ymin + obstacle.ymax) / 2
            markers.append(marker(k, "obstacles", CUBE, pose(cx, cy, 0.0),
                                  (obstacle.xmax - obstacle.xmin, obstacle.ymax - obstacle.ymin,
                                   0.3), (0.3, 0.3, 0.3, 0.8)))
        elif isinstance(obstacle, DiscObstacle):
            markers.append(marker(k, "obstacles", CYLINDER, pose(*obstacle.center, 0.0),
                                  (2 * obstacle.radius, 2 * obstacle.radius, 0.3),
                                  (0.3, 0.3, 0.3, 0.8)))
    for k, region in enumerate(scenario.regions):
        x, y = region.center
        markers.append(marker(k, "regions", CYLINDER, pose(x, y, 0.0),
                              (2 * region.radius, 2 * region.radius, 0.01),
                              (0.2, 0.6, 1.0, 0.35)))
        markers.append(marker(k, "region_names", TEXT, pose(x, y, 0.2), (0.0, 0.0, 0.15),
                              (1.0, 1.0, 1.0, 1.0), text=region.name))
    from tlfleet.coordinator.report.run_report import subtask_goals

    for k, (_robot, a, b, (rid, x, y, tolerance)) in enumerate(subtask_goals(scenario)):
        markers.append(marker(k, "stl_goals", CYLINDER, pose(x, y, 0.0),
                              (2 * tolerance, 2 * tolerance, 0.02), (1.0, 0.55, 0.0, 0.5)))
        markers.append(marker(k, "stl_goal_names", TEXT, pose(x, y, 0.25), (0.0, 0.0, 0.12),
                              (1.0, 0.8, 0.5, 1.0), text=f"goal {rid} [{a:g}, {b:g}] s"))
    return {"markers": markers}
