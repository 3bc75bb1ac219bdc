"""``tlfleet export-mcap``: a run directory written as MCAP with ROS 2 encodings, read back by an
independent decoder (rosbags: its own MCAP reader and CDR deserializer, its own reading of the
schema text) and compared with the run's files parsed here; the message definitions compared
with the ROS 2 wheels' own ``.msg`` files."""

from __future__ import annotations

import csv
import importlib.util
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
pytestmark = pytest.mark.ros


@pytest.fixture(autouse=True)
def _needs_mcap():
    for module in ("mcap_ros2", "rosbags"):
        if importlib.util.find_spec(module) is None:
            pytest.skip(f"needs {module}: the tlfleet[ros2] and test extras")


def make_run(tmp_path: Path) -> Path:
    """A run directory of tests/ros/four_robots.toml: 3 s at 100 Hz of circles, two statuses,
    three events, a run.json."""
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(HERE / "four_robots.toml", run / "scenario.toml")
    t = np.arange(0, 3.0001, 0.01)
    with open(run / "trajectory.csv", "w", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(["t"] + [f"{c}{r}" for r in (1, 2, 3, 4) for c in ("x", "y", "th")])
        for ti in t:
            row = [ti]
            for r in (1, 2, 3, 4):
                a = 0.5 * r * ti
                row += [math.cos(a) + r, math.sin(a), math.atan2(math.sin(a + 2), math.cos(a + 2))]
            w.writerow([repr(float(v)) for v in row])
    (run / "status.csv").write_text("t,robot,kind,rho,target\n0.1,3,stl,-0.25,\n0.2,1,ltl,,a1\n")
    events = [{"t": 0.5, "source": "sim", "kind": "contact", "data": {"a": 1, "b": 2}},
              {"t": 1.0, "source": "agent/3", "kind": "repair", "data": {"stage": 1, "r": 0.1}},
              {"t": 2.0, "source": "sim", "kind": "tracking_lost",
               "data": {"robots": [2], "age": {"2": 0.6}, "lost_after": 0.5}}]
    (run / "events.jsonl").write_text("".join(json.dumps(e) + "\n" for e in events))
    (run / "run.json").write_text(json.dumps({"scenario": "four_robots", "mode": "realtime",
                                              "duration": 3.0}))
    return run


def read_back(path: Path) -> dict[str, list]:
    from rosbags.highlevel import AnyReader

    out: dict[str, list] = {}
    with AnyReader([path]) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append((t, conn.msgtype,
                                                   reader.deserialize(raw, conn.msgtype)))
    return out


def yaw(q) -> float:
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def test_export_read_back_by_rosbags(tmp_path):
    run = make_run(tmp_path)
    proc = subprocess.run([sys.executable, "-m", "tlfleet.cli", "export-mcap", str(run)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    path = run / "run.mcap"
    assert proc.stdout.strip() == str(path)
    got = read_back(path)
    with open(run / "trajectory.csv", newline="") as handle:
        rows = np.array(list(csv.reader(handle))[1:], dtype=float)
    t = rows[:, 0]
    for j, robot in enumerate((1, 2, 3, 4)):
        poses = got[f"/robot{robot}/pose"]
        assert len(poses) == len(t) and poses[0][1] == "geometry_msgs/msg/PoseStamped"
        x = np.array([m.pose.position.x for _, _, m in poses])
        th = np.array([yaw(m.pose.orientation) for _, _, m in poses])
        stamps = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
                           for _, _, m in poses])
        assert np.allclose(x, rows[:, 1 + 3 * j], atol=1e-12)
        assert np.allclose(np.cos(th - rows[:, 3 + 3 * j]), 1.0, atol=1e-12)
        assert np.allclose(stamps, t, atol=1e-9)
        assert {m.header.frame_id for _, _, m in poses} == {"world"}
        assert np.allclose([ns for ns, _, _ in poses], np.round(t * 1e9))  # log times
        # the measured velocity: numpy's central differences of the recorded positions
        vx = np.array([m.twist.linear.x for _, _, m in got[f"/robot{robot}/velocity"]])
        assert np.allclose(vx, np.gradient(rows[:, 1 + 3 * j], t), atol=1e-6)
        w = np.array([m.twist.angular.z for _, _, m in got[f"/robot{robot}/velocity"]])
        assert np.allclose(w[1:-1], 0.5 * robot, atol=1e-6)  # dθ/dt of the circle, wraps too
        odom = got[f"/robot{robot}/odom"][150][2]
        assert odom.child_frame_id == f"robot{robot}"
        speed = 0.5 * robot  # on a unit circle
        assert math.hypot(odom.twist.twist.linear.x, odom.twist.twist.linear.y) == \
            pytest.approx(speed, rel=1e-4)
    arrays = got["/fleet/poses"]
    assert len(arrays) == len(t) and len(arrays[7][2].poses) == 4
    assert arrays[7][2].poses[2].position.y == pytest.approx(rows[7, 8])
    (scene,) = got["/scene"]
    names = [m.text for m in scene[2].markers if m.ns == "region_names"]
    assert names == ["a1", "a2"]
    discs = [m for m in scene[2].markers if m.ns == "regions"]
    assert discs[1].pose.position.x == 2.0 and discs[1].scale.x == pytest.approx(0.5)
    goals = [m.text for m in scene[2].markers if m.ns == "stl_goal_names"]
    assert goals == []  # four_robots.toml's STL tasks name no goal point
    statuses = [m.status[0] for _, _, m in got["/fleet/status"]]
    assert [s.name for s in statuses] == ["robot3", "robot1"]
    assert {kv.key: kv.value for kv in statuses[0].values} == {"kind": "stl", "rho": "-0.25"}
    events = [m.status[0] for _, _, m in got["/fleet/events"]]
    assert [(e.name, e.message, e.level) for e in events] == [
        ("sim", "contact", 1), ("agent/3", "repair", 0), ("sim", "tracking_lost", 1)]
    assert {kv.key: kv.value for kv in events[2].values}["robots"] == "[2]"


def test_the_file_is_a_ros2_mcap_with_statistics_and_metadata(tmp_path):
    from mcap.reader import make_reader
    from tlfleet.coordinator.report.mcap_export import export_mcap

    path = export_mcap(make_run(tmp_path), tmp_path / "x.mcap")
    with open(path, "rb") as handle:
        reader = make_reader(handle)
        header, summary = reader.get_header(), reader.get_summary()
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert header.profile == "ros2"
    assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
    assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
    assert summary.statistics.message_count == 301 * 13 + 1 + 2 + 3  # rosbag2 reads these
    assert metadata["tlfleet"]["mode"] == "realtime"


def _msg_fields(text: str) -> list[tuple[str, str]]:
    """(type, name) of the fields of one .msg text: comments, constants and defaults dropped."""
    out = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        kind, name = line.split()[:2]
        if "=" in name or "=" in line.split()[1:2][0]:
            continue
        out.append((kind.split("/")[-1], name))
    return out


@pytest.mark.skipif(importlib.util.find_spec("rclpy") is None, reason="needs the ROS 2 wheels")
def test_the_definitions_match_the_ros_wheels_msg_files():
    """Every type written, and every type it uses, has the fields of the installed ROS 2
    message (share/<pkg>/msg/<Name>.msg of the wheels), in order."""
    from tlfleet.coordinator.report import ros_messages as rm

    share = Path(sys.prefix) / "share"
    checked = 0
    for full in rm.TYPES:
        text = rm.definition(full)
        blocks = text.split("=" * 80 + "\n")
        names = [full.replace("/msg/", "/")] + [b.split("\n", 1)[0][5:] for b in blocks[1:]]
        bodies = [blocks[0]] + [b.split("\n", 1)[1] for b in blocks[1:]]
        for name, body in zip(names, bodies, strict=True):
            package, short = name.split("/")
            msg = share / package / "msg" / f"{short}.msg"
            assert msg.exists(), msg
            assert _msg_fields(body) == _msg_fields(msg.read_text()), name
            checked += 1
    assert checked > 20


def test_the_scene_marks_scenario_1s_stl_goals():
    from tlfleet.agent.scenario import load_scenario
    from tlfleet.coordinator.report.ros_messages import scene_markers

    markers = scene_markers(load_scenario(ROOT / "scenarios" / "scenario1.toml"))["markers"]
    goals = {(m["pose"]["position"]["x"], m["pose"]["position"]["y"], m["scale"]["x"])
             for m in markers if m["ns"] == "stl_goals"}
    # the goal points of Scenario 1's sub-tasks (scenarios/scenario1.toml), radius 0.1 each
    assert {(0.0, -2.0, 0.2), (0.0, 2.0, 0.2), (1.5, -1.5, 0.2), (2.0, 2.0, 0.2),
            (-1.0, 0.5, 0.2)} <= goals
    assert "goal 3 [57, 58] s" in {m["text"] for m in markers if m["ns"] == "stl_goal_names"}
