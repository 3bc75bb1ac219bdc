"""The ROS-free parts of the hardware bridge: REP 103 frame conversions (against rotation
matrices built here with numpy), lab files (file, field, reason), the safety rules on a fake
clock, and :class:`HardwareWorld` with a recording link."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from tlfleet.agent.scenario import load_scenario
from tlfleet.agent.scenario.lab import check_lab, load_lab, parse_lab
from tlfleet.agent.scenario.rep103 import (
    apply_offset,
    body_to_world,
    quaternion_of_yaw,
    twist_of_command,
    world_to_body,
    yaw_of_quaternion,
)
from tlfleet.bus.errors import ScenarioError
from tlfleet.sim.hardware.safety import Safety, SafetyConfig, Send, clip_command
from tlfleet.sim.hardware.world import HardwareWorld

HERE = Path(__file__).resolve().parent
FLEET = HERE / "four_robots.toml"
angles = st.floats(-10.0, 10.0, allow_nan=False)
speeds = st.floats(-2.0, 2.0, allow_nan=False)


def rot(yaw: float) -> np.ndarray:
    return np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])


def quat_to_matrix(x, y, z, w) -> np.ndarray:
    """The 3×3 rotation matrix of a unit quaternion (the textbook formula)."""
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


# --------------------------------------------------------------------------- REP 103


@given(angles)
def test_yaw_quaternion_round_trip(yaw):
    q = quaternion_of_yaw(yaw)
    assert math.isclose(sum(v * v for v in q), 1.0, abs_tol=1e-12)
    back = yaw_of_quaternion(*q)
    assert math.isclose(math.cos(back - yaw), 1.0, abs_tol=1e-9)
    # the quaternion's matrix is the planar rotation by yaw
    assert np.allclose(quat_to_matrix(*q)[:2, :2], rot(yaw), atol=1e-12)


@given(angles, st.floats(-0.5, 0.5), st.floats(-0.5, 0.5), st.floats(0.1, 5.0))
def test_yaw_of_a_tilted_unnormalised_quaternion_is_the_heading_of_its_x_axis(yaw, roll, pitch,
                                                                              scale):
    """A body rolled and pitched a little (mocap noise) still heads where its x axis points in
    the plane: yaw = atan2 of the rotated x axis's y and x (the Z-Y-X yaw)."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll / 2), math.sin(roll / 2), math.cos(pitch / 2),
                              math.sin(pitch / 2), math.cos(yaw / 2), math.sin(yaw / 2))
    q = (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy,
         cr * cp * cy + sr * sp * sy)
    x_axis = quat_to_matrix(*q) @ np.array([1.0, 0.0, 0.0])
    expected = math.atan2(x_axis[1], x_axis[0])
    got = yaw_of_quaternion(*(scale * v for v in q))
    assert math.isclose(math.cos(got - expected), 1.0, abs_tol=1e-9)


def test_a_zero_quaternion_is_an_error():
    with pytest.raises(ValueError, match="no rotation"):
        yaw_of_quaternion(0.0, 0.0, 0.0, 0.0)


@given(speeds, speeds, angles)
def test_world_to_body_is_the_transposed_rotation(vx, vy, yaw):
    body = world_to_body(vx, vy, yaw)
    assert np.allclose(body, rot(yaw).T @ np.array([vx, vy]), atol=1e-12)
    assert np.allclose(body_to_world(*body, yaw), (vx, vy), atol=1e-12)


def test_world_to_body_by_hand():
    # heading +y (90°): a world velocity +x is the robot's right, −y in its body frame
    assert np.allclose(world_to_body(1.0, 0.0, math.pi / 2), (0.0, -1.0), atol=1e-15)
    assert np.allclose(world_to_body(0.0, 1.0, math.pi / 2), (1.0, 0.0), atol=1e-15)


@given(st.floats(-3, 3), st.floats(-3, 3), angles, st.floats(-0.3, 0.3), st.floats(-0.3, 0.3),
       st.floats(-1, 1))
def test_pose_offset_is_a_composition_of_rigid_transforms(x, y, yaw, dx, dy, dpsi):
    """T_world_robot = T_world_body · T_body_robot, with homogeneous matrices."""
    def h(px, py, a):
        m = np.eye(3)
        m[:2, :2], m[:2, 2] = rot(a), (px, py)
        return m

    expected = h(x, y, yaw) @ h(dx, dy, dpsi)
    rx, ry, ryaw = apply_offset(x, y, yaw, (dx, dy, dpsi))
    assert np.allclose(h(rx, ry, ryaw), expected, atol=1e-9)
    assert -math.pi < ryaw <= math.pi


def test_twist_of_command():
    assert twist_of_command("unicycle", (0.2, -0.5), 1.0) == (0.2, 0.0, -0.5)
    assert np.allclose(twist_of_command("omni", (0.1, 0.0, 0.3), math.pi), (-0.1, 0.0, 0.3))
    with pytest.raises(ValueError):
        twist_of_command("boat", (1.0,), 0.0)


# --------------------------------------------------------------------------- lab files

GOOD = """
[ros]
domain_id = 7
discovery_range = "LOCALHOST"
cmd_stamp = "zero"

[mocap]
lost_after = 0.1

[[robots]]
id = 1
mocap = { topic = "/vrpn_mocap/tb1/pose" }
cmd = { topic = "/tb1/cmd_vel", type = "geometry_msgs/Twist", repeat_hz = 25 }
pose_offset = [0.01, 0.0, 0.05]
robot_timeout = 0.5
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "lab.toml"
    path.write_text(text)
    return path


def test_a_good_lab_file(tmp_path):
    lab = load_lab(write(tmp_path, GOOD))
    (robot,) = lab.robots
    assert (lab.domain_id, lab.discovery_range, lab.cmd_stamp) == (7, "LOCALHOST", "zero")
    assert robot.mocap_type == "geometry_msgs/msg/PoseStamped"  # the default
    assert robot.cmd_type == "geometry_msgs/msg/Twist"  # short form accepted, made canonical
    assert robot.pose_offset == (0.01, 0.0, 0.05) and robot.repeat_hz == 25.0
    assert lab.ros_environment() == {"ROS_DOMAIN_ID": "7",
                                     "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}


@pytest.mark.parametrize(("change", "field", "reason"), [
    (("domain_id = 7", "domain_id = 300"), "ros.domain_id", "in [0, 232]"),
    (('"LOCALHOST"', '"LAN"'), "ros.discovery_range", "expected one of 'SUBNET'"),
    (('cmd_stamp = "zero"', 'cmd_stamp = "later"'), "ros.cmd_stamp", "'now'"),
    (("lost_after = 0.1", "lost_after = -1"), "mocap.lost_after", "positive"),
    (('"/tb1/cmd_vel"', '"tb1 cmd"'), "robots[0].cmd.topic", "ROS topic name"),
    (('"geometry_msgs/Twist"', '"std_msgs/msg/String"'), "robots[0].cmd.type",
     "geometry_msgs/msg/TwistStamped"),
    (("repeat_hz = 25", "repeat_hz = 0"), "robots[0].cmd.repeat_hz", "positive"),
    (("pose_offset = [0.01, 0.0, 0.05]", "pose_offset = [0.01]"), "robots[0].pose_offset",
     "list of 3 numbers"),
    (("robot_timeout = 0.5", "robot_timout = 0.5"), "robots[0].robot_timout", "robot_timeout"),
    (("repeat_hz = 25", "repeat_hz = 1"), "robots[0].cmd.repeat_hz",
     "not within the robot's own timeout"),
])
def test_lab_file_errors_name_the_file_the_field_and_the_reason(tmp_path, change, field, reason):
    path = write(tmp_path, GOOD.replace(*change))
    with pytest.raises(ScenarioError) as info:
        lab = load_lab(path)
        check_lab(lab, load_scenario(HERE.parent / "system" / "two_robots.toml"))
    assert info.value.file == str(path) and info.value.field == field
    assert reason in info.value.reason


def test_the_lab_must_drive_exactly_the_scenarios_robots(tmp_path):
    scenario = load_scenario(FLEET)  # robots 1-4
    with pytest.raises(ScenarioError, match=r"robot\(s\) 2, 3, 4 without a \[\[robots\]\]"):
        check_lab(load_lab(write(tmp_path, GOOD)), scenario)
    extra = GOOD + GOOD[GOOD.index("[[robots]]"):].replace("id = 1", "id = 9").replace(
        "tb1", "tb9")
    with pytest.raises(ScenarioError) as info:
        check_lab(load_lab(write(tmp_path, extra)), load_scenario(
            HERE.parent / "system" / "two_robots.toml"))
    assert info.value.field == "robots[1].id" and "robot 9 is not in scenario" in info.value.reason


def test_duplicate_topics_are_errors():
    twice = GOOD + GOOD[GOOD.index("[[robots]]"):].replace("id = 1", "id = 2").replace(
        "/tb1/cmd_vel", "/tb2/cmd_vel")
    with pytest.raises(ScenarioError) as info:
        parse_lab(__import__("tomllib").loads(twice), "lab.toml")
    assert info.value.field == "robots[1].mocap.topic" and "duplicate" in info.value.reason


# --------------------------------------------------------------------------- safety rules


def safety(repeat: float = 0.05, watchdog: float = 0.5, lost: float = 0.1) -> Safety:
    config = SafetyConfig(watchdog=watchdog, lost_after=lost, fence=(-1.0, 1.0, -1.0, 1.0),
                          repeat_period={1: repeat, 2: repeat})
    s = Safety(config, {1: "unicycle", 2: "omni"})
    for robot in (1, 2):
        s.pose(robot, 0.0, 0.0, 0.0, 0.0)
    return s


def test_nothing_goes_out_before_the_start():
    s = safety()
    assert s.command(1, (0.1, 0.0), 0.0) == []
    assert s.tick(0.2) == ([], [], [])
    assert s.dropped["before_start"] == 1
    s.start(0.3)
    assert s.command(1, (0.1, 0.0), 0.3) == [Send(1, (0.1, 0.0), "command")]


def test_keepalive_resends_the_newest_command_at_its_rate():
    s = safety(repeat=0.05)
    s.start(0.0)
    s.command(1, (0.1, 0.2), 0.0)
    sent = []
    for k in range(1, 41):  # 0.4 s of 100 Hz ticks, poses fresh
        now = k * 0.01
        for r in (1, 2):
            s.pose(r, 0.0, 0.0, 0.0, now)
        sends, stopped, events = s.tick(now)
        assert stopped == [] and events == []
        sent += [(now, x) for x in sends]
    assert all(x == Send(1, (0.1, 0.2), "keepalive") for _, x in sent)  # robot 2: never commanded
    times = [t for t, _ in sent]
    assert len(times) == 8 and np.allclose(np.diff(times), 0.05)


def test_the_watchdog_stops_a_silent_robot_once_then_keeps_it_at_zero():
    s = safety(repeat=1.0, watchdog=0.5)
    s.start(0.0)
    s.command(2, (0.1, 0.0, 0.3), 0.0)
    for now in (0.25, 0.5):
        s.pose(1, 0, 0, 0, now)
        s.pose(2, 0, 0, 0, now)
        assert s.tick(now)[1] == []
    s.pose(1, 0, 0, 0, 0.51)
    s.pose(2, 0, 0, 0, 0.51)
    sends, stopped, _ = s.tick(0.51)
    assert stopped == [2] and sends == [Send(2, (0.0, 0.0, 0.0), "watchdog")]
    s.pose(1, 0, 0, 0, 0.6)
    s.pose(2, 0, 0, 0, 0.6)
    assert s.tick(0.6)[1] == []  # reported once
    assert s.command(2, (0.1, 0.0, 0.0), 0.6) == [Send(2, (0.1, 0.0, 0.0), "command")]


def test_a_lost_body_halts_everybody_and_the_halt_is_latched():
    s = safety(lost=0.1)
    s.start(0.0)
    s.command(1, (0.1, 0.0), 0.0)
    s.pose(1, 0, 0, 0, 0.1)  # robot 2 last seen at 0.0
    sends, _, events = s.tick(0.1)
    assert events == []
    sends, _, events = s.tick(0.11)
    assert [e.kind for e in events] == ["tracking_lost"] and events[0].data["robots"] == [2]
    assert sends == [Send(1, (0.0, 0.0), "halt"), Send(2, (0.0, 0.0, 0.0), "halt")]
    for r in (1, 2):
        s.pose(r, 0, 0, 0, 0.2)  # back: still halted
    assert s.command(1, (0.1, 0.0), 0.2) == [] and s.dropped["halted"] == 1
    sends, _, events = s.tick(0.2)
    assert events == [] and {x.u for x in sends} <= {(0.0, 0.0), (0.0, 0.0, 0.0)}


def test_a_body_never_seen_counts_as_lost_after_the_start():
    config = SafetyConfig(0.5, 0.1, (-1, 1, -1, 1), {1: 0.05})
    s = Safety(config, {1: "omni"})
    s.start(0.0)
    assert s.tick(0.1)[2] == []
    assert s.tick(0.11)[2][0].data == {"robots": [1], "age": {"1": None}, "lost_after": 0.1}


def test_the_geofence():
    s = safety()
    s.start(0.0)
    s.pose(2, 1.0, -0.5, 0.0, 0.01)  # on the fence: inside
    assert s.tick(0.01)[2] == []
    s.pose(2, 1.01, -0.5, 0.0, 0.02)
    s.pose(1, 0.0, 0.0, 0.0, 0.02)
    _, _, events = s.tick(0.02)
    assert events[0].kind == "geofence" and events[0].data["robot"] == 2


def test_stop_sends_zero_to_everybody_and_ends_the_commands():
    s = safety()
    sends = s.stop(1.0)  # also before any start
    assert sends == [Send(1, (0.0, 0.0), "stop"), Send(2, (0.0, 0.0, 0.0), "stop")]
    assert s.command(1, (0.1, 0.0), 1.1) == [] and s.tick(1.2) == ([], [], [])


def test_commands_are_clipped_like_the_simulator_clips_them():
    scenario = load_scenario(FLEET)
    uni, omni = scenario.robots[0], scenario.robots[2]
    v, w = clip_command(uni, (5.0, -9.0))
    assert (v, w) == (uni.unicycle.max_v, -uni.unicycle.max_omega)
    vx, vy, w = clip_command(omni, (3.0, 4.0, 0.1))
    assert math.isclose(math.hypot(vx, vy), omni.omni.max_lin) and math.isclose(vy / vx, 4 / 3)
    with pytest.raises(ValueError, match="expects 3"):
        clip_command(omni, (0.1, 0.1))
    with pytest.raises(ValueError, match="non-finite"):
        clip_command(uni, (math.nan, 0.0))


# --------------------------------------------------------------------------- HardwareWorld


class Recorder:
    def __init__(self):
        self.sent: list[tuple[int, tuple[float, float, float]]] = []

    def send(self, robot, twist):
        self.sent.append((robot, twist))


def hardware(tmp_path, now):
    from ros_harness import lab_toml

    scenario = load_scenario(FLEET)
    path = write(tmp_path, lab_toml([(r.id, r.kind) for r in scenario.robots], 5))
    link = Recorder()
    return HardwareWorld(scenario, load_lab(path), link, now=lambda: now[0]), link


def test_the_world_sends_omni_commands_in_the_body_frame_of_the_newest_pose(tmp_path):
    now = [0.0]
    world, link = hardware(tmp_path, now)
    for robot in (1, 2, 3, 4):
        world.on_pose(robot, 0.5 * robot, 0.0, 0.0)
    world.on_pose(3, -1.0, 0.0, math.pi / 2)
    world.start()
    assert world.command(3, (0.1, 0.0, 0.2))
    robot, twist = link.sent[-1]
    assert robot == 3 and np.allclose(twist, (0.0, -0.1, 0.2), atol=1e-15)
    assert world.command(1, (0.3, 0.4))  # clipped: max_v 0.3 (default), max_omega 1.0
    assert link.sent[-1] == (1, (0.3, 0.0, 0.4))
    assert world.mocap_poses()[2] == (3, -1.0, 0.0, pytest.approx(math.pi / 2))


def test_contacts_from_the_poses_are_reported_at_their_onset(tmp_path):
    now = [0.0]
    world, _ = hardware(tmp_path, now)
    world.on_pose(1, 0.0, 0.0, 0.0)
    world.on_pose(2, 0.3, 0.0, 0.0)  # radii 0.2 + 0.2 > 0.3: touching
    world.on_pose(3, -3.4, 0.0, 0.0)  # 0.1 m from the wall, radius 0.2: touching the arena
    world.on_pose(4, 2.0, 2.0, 0.0)
    world.start()
    world.step(0.01)
    contacts = {(c.a, c.b, c.what) for c in world.drain_contacts()}
    assert contacts == {(1, 2, ""), (3, "wall", "arena")}
    world.step(0.01)
    assert world.drain_contacts() == []  # still touching: no new onset
    world.on_pose(2, 1.0, 0.0, 0.0)
    world.step(0.01)
    world.on_pose(2, 0.35, 0.0, 0.0)
    world.step(0.01)
    assert [(c.a, c.b) for c in world.drain_contacts()] == [(1, 2)]  # a new onset


def test_polled_poses_reach_frames_and_rules_also_after_a_stalled_loop(tmp_path):
    """The bridge's poses are pulled (RosLink.poll): a frame's poses are polled for it, and the
    safety rules poll again when the loop stalled since — poses that came meanwhile are not
    taken for a lost body. The rules do not poll again soon after a frame's poll."""
    now = [0.0]
    world, _ = hardware(tmp_path, now)
    arrived: list[tuple[int, float, float, float]] = []
    polls = []

    def poll():
        polls.append(now[0])
        while arrived:
            world.on_pose(*arrived.pop(0))

    world.poll = poll
    arrived.extend((r, 0.5 * r, 0.0, 0.0) for r in (1, 2, 3, 4))
    assert world.missing_poses() == []
    world.start()
    arrived.append((2, 1.25, 0.0, 0.0))
    assert world.mocap_poses()[1] == (2, 1.25, 0.0, 0.0)
    n = len(polls)
    now[0] += 0.01  # 100 Hz frames: 1.5 periods, within a quarter of lost_after (0.5 s)
    assert world.poll_fresh == pytest.approx(0.015)
    world.step(0.01)  # one frame period after the frame's poll: no second one
    assert len(polls) == n
    for _ in range(10):  # the loop stalls 1 s (lost_after 0.5 s) while the bodies move on
        now[0] += 0.1
        arrived.extend((r, 0.5 * r, 0.1, 0.0) for r in (1, 2, 3, 4))
    assert world.check_watchdog(now[0]) == []
    assert world.drain_events() == [] and world.safety.halted is None
    assert world.mocap_poses()[0] == (1, 0.5, 0.1, 0.0)
    now[0] += 1.0  # nothing came for 1 s: lost
    world.step(0.01)
    assert [e.kind for e in world.drain_events()] == ["tracking_lost"]


def test_the_documented_lab_fits_scenario_1():
    root = HERE.parent.parent
    lab = load_lab(root / "docs" / "labs" / "turtlebot4_vrpn.toml")
    check_lab(lab, load_scenario(root / "scenarios" / "scenario1.toml"))
    assert [r.cmd_type for r in lab.robots] == ["geometry_msgs/msg/TwistStamped"] * 5
