"""``tlfleet export-mcap RUN_DIR``: a run directory as an MCAP file with ROS 2 encodings
(profile ``ros2``, schemas ``ros2msg``, messages ``cdr``), which Foxglove and ``ros2 bag`` read
(docs/hardware.md §MCAP). No ROS needed: the ``mcap`` and ``mcap-ros2-support`` packages
(pure Python, the ``tlfleet[ros2]`` extra) encode the messages of :mod:`.ros_messages`.

Channels (times are the run's sim time since the start, as nanoseconds; the file's log times are
the same, so a player replays the mission from t = 0):

* ``/robot<id>/pose`` — ``geometry_msgs/msg/PoseStamped`` in ``world``, every recorded frame;
* ``/robot<id>/velocity`` — ``geometry_msgs/msg/TwistStamped`` in ``world``: the velocity
  *measured* from consecutive frames (central differences; the run directory holds no commands);
* ``/robot<id>/odom`` — ``nav_msgs/msg/Odometry``: pose in ``world``, that velocity in the body
  frame ``robot<id>``;
* ``/fleet/poses`` — ``geometry_msgs/msg/PoseArray`` of every robot, ids ascending;
* ``/fleet/status`` — ``diagnostic_msgs/msg/DiagnosticArray``: each row of ``status.csv`` as one
  ``DiagnosticStatus`` named ``robot<id>`` whose key-values are the row's columns;
* ``/fleet/events`` — ``diagnostic_msgs/msg/DiagnosticArray``: each event of ``events.jsonl``
  (``name`` = its source, ``message`` = its kind, ``values`` = its data; contacts, watchdog
  stops and the bridge's halts at level WARN);
* ``/scene`` — ``visualization_msgs/msg/MarkerArray``: arena, obstacles, regions, at t = 0;

plus a ``tlfleet`` metadata record with ``run.json``'s top-level values as text.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.errors import TlfleetError
from tlfleet.coordinator.report import ros_messages as rm

WARN_KINDS = frozenset({"contact", "watchdog_stop", "stale_command", "deadline_miss",
                        "tracking_lost", "geofence", "process_died"})


class ExportError(TlfleetError):
    """The run directory cannot be exported (names the file and why)."""


def _ns(t: float) -> int:
    return max(0, round(t * 1e9))


def read_trajectory(run_dir: Path) -> tuple[list[int], list[list[float]]]:
    """``(robot ids, rows)`` of ``trajectory.csv``: each row ``[t, x1, y1, th1, x2, ...]``."""
    path = run_dir / "trajectory.csv"
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        raise ExportError(f"{path}: cannot read: {exc.strerror}") from None
    if not rows or rows[0][:1] != ["t"] or (len(rows[0]) - 1) % 3:
        raise ExportError(f"{path}: expected a header t,x<id>,y<id>,th<id>,...")
    ids = [int(name[1:]) for name in rows[0][1::3]]
    data = []
    for line, row in enumerate(rows[1:], start=2):
        try:
            data.append([float(v) for v in row])
        except ValueError:
            raise ExportError(f"{path}:{line}: not a row of numbers") from None
    return ids, data


def velocities(rows: list[list[float]], k: int) -> list[tuple[float, float, float]]:
    """Each robot's world-frame velocity ``(vx, vy, ω)`` at row ``k`` [m/s, rad/s]: central
    differences (one-sided at the ends), the heading's difference wrapped to (−π, π]."""
    lo, hi = max(0, k - 1), min(len(rows) - 1, k + 1)
    if hi == lo:
        return [(0.0, 0.0, 0.0)] * ((len(rows[k]) - 1) // 3)
    a, b = rows[lo], rows[hi]
    dt = b[0] - a[0]
    out = []
    for j in range(1, len(a), 3):
        dth = math.atan2(math.sin(b[j + 2] - a[j + 2]), math.cos(b[j + 2] - a[j + 2]))
        out.append(((b[j] - a[j]) / dt, (b[j + 1] - a[j + 1]) / dt, dth / dt) if dt > 0
                   else (0.0, 0.0, 0.0))
    return out


def export_mcap(run_dir: Path, out: Path | None = None) -> Path:
    """Write ``run_dir``'s MCAP file (default ``run_dir/run.mcap``); returns its path."""
    from mcap_ros2.writer import Writer  # the tlfleet[ros2] extra

    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "run.mcap"
    scenario = load_scenario(run_dir / "scenario.toml")
    ids, rows = read_trajectory(run_dir)
    tmp = out.with_suffix(out.suffix + ".part")
    with open(tmp, "wb") as handle:
        writer = Writer(handle)
        schema = {name: writer.register_msgdef(name, rm.definition(name)) for name in rm.TYPES}
        pose_s, array_s = schema["geometry_msgs/msg/PoseStamped"], schema[
            "geometry_msgs/msg/PoseArray"]
        twist_s, odom_s = schema["geometry_msgs/msg/TwistStamped"], schema[
            "nav_msgs/msg/Odometry"]
        diag_s = schema["diagnostic_msgs/msg/DiagnosticArray"]
        writer.write_message("/scene", schema["visualization_msgs/msg/MarkerArray"],
                             rm.scene_markers(scenario), log_time=0, publish_time=0)
        for k, row in enumerate(rows):
            t, ns = row[0], _ns(row[0])
            poses = [(row[1 + 3 * j], row[2 + 3 * j], row[3 + 3 * j]) for j in range(len(ids))]
            vel = velocities(rows, k)
            for j, robot in enumerate(ids):
                writer.write_message(f"/robot{robot}/pose", pose_s,
                                     rm.pose_stamped(t, *poses[j]), log_time=ns, publish_time=ns)
                writer.write_message(f"/robot{robot}/velocity", twist_s,
                                     rm.twist_stamped(t, *vel[j]), log_time=ns, publish_time=ns)
                writer.write_message(f"/robot{robot}/odom", odom_s,
                                     rm.odometry(t, robot, poses[j], vel[j]), log_time=ns,
                                     publish_time=ns)
            writer.write_message("/fleet/poses", array_s, rm.pose_array(t, poses), log_time=ns,
                                 publish_time=ns)
        for t, status in _statuses(run_dir):
            writer.write_message("/fleet/status", diag_s, rm.diagnostic_array(t, [status]),
                                 log_time=_ns(t), publish_time=_ns(t))
        for t, status in _events(run_dir):
            writer.write_message("/fleet/events", diag_s, rm.diagnostic_array(t, [status]),
                                 log_time=_ns(t), publish_time=_ns(t))
        info = _run_info(run_dir)
        if info:
            writer.add_metadata("tlfleet", info)
        writer.finish()
    tmp.replace(out)
    return out


def _statuses(run_dir: Path) -> list[tuple[float, dict[str, Any]]]:
    path = run_dir / "status.csv"
    if not path.exists():
        return []
    out = []
    with open(path, newline="", encoding="utf-8") as handle:
        for row in csv.DictReader(handle):
            try:
                t = float(row.get("t", "nan"))
            except ValueError:
                continue
            if not math.isfinite(t):
                continue
            values = {k: v for k, v in row.items() if k not in ("t", "robot") and v != ""}
            out.append((t, rm.diagnostic_status(f"robot{row.get('robot', '?')}", values)))
    return sorted(out, key=lambda item: item[0])


def _events(run_dir: Path) -> list[tuple[float, dict[str, Any]]]:
    path = run_dir / "events.jsonl"
    if not path.exists():
        return []
    out = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            event = json.loads(line)
            t = float(event["t"])
        except (ValueError, KeyError, TypeError):
            continue
        if not math.isfinite(t):
            continue
        data = event.get("data") if isinstance(event.get("data"), dict) else {}
        kind = str(event.get("kind", ""))
        values = {k: json.dumps(v) if isinstance(v, dict | list) else v for k, v in data.items()}
        out.append((t, rm.diagnostic_status(str(event.get("source", "")), values,
                                            level=1 if kind in WARN_KINDS else 0, message=kind)))
    return sorted(out, key=lambda item: item[0])


def _run_info(run_dir: Path) -> dict[str, str]:
    try:
        info = json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if not isinstance(info, dict):
        return {}
    return {str(k): v if isinstance(v, str) else json.dumps(v) for k, v in info.items()}
