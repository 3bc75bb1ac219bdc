"""The hardware bridge against real rclpy fake robots (no mock of ROS), each case in a network
namespace of its own with a private /dev/shm and its own ROS domain (ros_harness).

The fleet is tests/ros/four_robots.toml: two unicycles (robots 1, 2) and two omni robots (3, 4)
as fake TurtleBot-like and mecanum robots. This script stands in for the coordinator and the
agents (ros_case.py): it starts the mission and sends commands answering the bridge's frames.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from ros_harness import need_ros, run_case, unique_domain

HERE = Path(__file__).resolve().parent
FLEET = str(HERE / "four_robots.toml")
WATCHDOG = 0.3  # [s] four_robots.toml's [sim] watchdog
LOST_AFTER = 0.5  # [s] the labs' [mocap] lost_after (ros_harness.lab_toml)
SLACK = 0.3  # [s] for a loaded test machine (a process stalled for 0.3 s was seen)
# commands answering frames up to 0.5 s old are sent (not 50 ms: the stand-in agents of ros_case
# answer frames on their own schedule, late on a loaded machine)
AGE = ["--max-command-age", "0.5"]
GOALS = {"1": [-1.0, -1.0], "2": [1.5, -1.0], "3": [-1.0, 1.0], "4": [1.5, 1.0]}
TWIST, STAMPED = "geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped"

pytestmark = [pytest.mark.system, pytest.mark.needs_system, pytest.mark.ros]


def by_robot(received: list[dict]) -> dict[str, list[dict]]:
    out: dict[str, list[dict]] = {}
    for row in received:
        out.setdefault(row["robot"][1:], []).append(row)
    return out


def is_zero(row: dict) -> bool:
    return all(v == 0.0 for v in row["u"])


def events_of(result: dict, kind: str) -> list[dict]:
    return [e for e in result.get("events", []) if e["kind"] == kind]


@pytest.fixture(scope="module")
def mission(tmp_path_factory) -> dict:
    """One mission through the bridge: commands before the start, the start, 8 s of go-to-goal
    control (omni robots spinning at 0.6 rad/s), 1.5 s in which robot 3's agent is silent, then
    SIGTERM to the bridge. QoS matrix: robot 1 reliable mocap + Twist, 2 best-effort +
    TwistStamped, 3 reliable + TwistStamped, 4 best-effort + Twist. Robots 1 and 2 are commanded
    at 5 Hz but time out after 0.15 s on their own: only the keep-alive keeps them going."""
    need_ros()
    case = {
        "kind": "bridge", "scenario": FLEET, "domain_id": unique_domain(), "args": AGE,
        "lab": {"cmd_types": {"1": TWIST, "4": TWIST}, "robot_timeout": 0.15},
        "robots": {"1": {"mocap_reliable": True, "cmd_type": TWIST, "cmd_timeout": 0.15},
                   "2": {"cmd_type": STAMPED, "cmd_timeout": 0.15},
                   "3": {"mocap_reliable": True, "cmd_type": STAMPED},
                   "4": {"cmd_type": TWIST}},
        "steps": [
            {"do": "stream", "s": 1.0, "rates": {"1": 5, "3": 50},
             "u": {"1": [0.2, 0.0], "3": [0.1, 0.0, 0.0]}},
            {"do": "start"},
            {"do": "stream", "s": 8.0, "rates": {"1": 5, "2": 5, "3": 100, "4": 100},
             "spin": 0.6, "goals": GOALS},
            {"do": "stream", "s": 1.5, "rates": {"1": 5, "2": 5, "4": 100}, "spin": 0.6,
             "goals": GOALS},
            {"do": "sigterm"},
            {"do": "wait_exit", "s": 15},
        ]}
    return run_case(case, tmp_path_factory.mktemp("mission"), timeout=120)


def test_no_command_reaches_a_robot_before_the_start(mission):
    start = mission["marks"]["start"][0]
    early = [row for row in mission["received"] if row["t"] < start]
    assert early == []
    assert {row["robot"] for row in mission["received"]} == {"r1", "r2", "r3", "r4"}


def test_closed_loop_both_kinds_every_qos_and_message_type(mission):
    """Each robot reaches its goal within 5 cm (true pose of the fake robot and the pose the
    bridge published) — a wrong body-frame rotation of the spinning omni robots, a wrong yaw
    from the quaternion or a QoS mismatch (no pose, no command) would not."""
    poses = mission["poses"][1]  # the bridge's frame at the end of the 8 s of control
    for robot, goal in GOALS.items():
        x, y, _ = poses[robot]
        assert math.hypot(x - goal[0], y - goal[1]) < 0.05, (robot, poses[robot])
    final = mission["robots_final"]  # where they stopped
    for robot, goal in GOALS.items():
        if robot != "3":
            x, y, _ = final[f"r{robot}"]
            assert math.hypot(x - goal[0], y - goal[1]) < 0.08, (robot, final)


def test_keepalive_keeps_slow_commands_alive(mission):
    """Robots 1 and 2 get a new command every 0.2 s but would stop 0.15 s after their last
    one: they receive one every 0.05 s (the lab's keep-alive, 20 Hz), 19 gaps in 20 below their
    timeout (a test machine shared with other fleets stalls a process for 0.3 s at times)."""
    start, term = mission["marks"]["start"][0], mission["marks"]["sigterm"][0]
    rows = by_robot(mission["received"])
    for robot in ("1", "2"):
        times = [r["t"] for r in rows[robot] if start + 0.5 < r["t"] < term]
        gaps = np.diff(times)
        assert len(times) > 100, (robot, len(times))
        assert 0.04 < float(np.median(gaps)) < 0.06, (robot, np.median(gaps))
        assert float(np.percentile(gaps, 95)) < 0.15, (robot, np.percentile(gaps, 95))


def test_a_silent_agent_trips_the_watchdog_zero_and_event(mission):
    silent_from = mission["marks"]["stream"][2]  # robot 3 gets no command from here on
    rows = by_robot(mission["received"])["3"]
    zeros = [r for r in rows if is_zero(r) and r["t"] > silent_from]
    assert zeros, "robot 3 never received a zero after its agent fell silent"
    assert zeros[0]["t"] - silent_from <= WATCHDOG + SLACK
    moving = [r for r in rows if not is_zero(r) and r["t"] > zeros[0]["t"]]
    assert moving == []
    stops = [e for e in events_of(mission, "watchdog_stop") if e["data"]["robot"] == 3]
    assert stops and silent_from < stops[-1]["wall"] <= zeros[0]["t"] + SLACK


def test_sigterm_zero_to_every_robot_before_the_bridge_exits(mission):
    assert mission["bridge_rc"] == 0, mission["hw_log"]
    term, exited = mission["marks"]["sigterm"][0], mission["marks"]["bridge_exit"][0]
    for robot, rows in by_robot(mission["received"]).items():
        after = [r for r in rows if r["t"] >= term]
        assert after and is_zero(after[-1]), (robot, after[-3:])
        first_zero = next(r for r in after if is_zero(r))
        assert first_zero["t"] < exited and first_zero["t"] - term <= 0.5, robot
    assert "sim_stats" in [e["kind"] for e in mission["events"]]


def test_a_lost_body_halts_every_robot(tmp_path):
    """Robot 2's rigid body vanishes 1 s into the mission: within the lab's lost_after (0.5 s
    in the tests' labs: a loaded test machine delays poses by 0.2 s at times) plus a tick every
    robot receives zero, nothing but zeros afterwards, one tracking_lost."""
    need_ros()
    case = {"kind": "bridge", "scenario": FLEET, "domain_id": unique_domain(), "args": AGE,
            "robots": {"2": {"lose_after": 1.0}},
            "steps": [{"do": "start"},
                      {"do": "stream", "s": 3.0, "rates": {"1": 5, "2": 5, "3": 100, "4": 100},
                       "goals": GOALS},
                      {"do": "stop"}, {"do": "wait_exit", "s": 15}]}
    result = run_case(case, tmp_path, timeout=90)
    rows = by_robot(result["received"])
    lost_at = rows["2"][0]["t"] + 1.0  # the fake body stops 1 s after its first command
    (event,) = events_of(result, "tracking_lost")
    assert event["data"]["robots"] == [2]
    for robot in ("1", "2", "3", "4"):
        # stopped for good: the zero after the last moving command came within the limit (not
        # "the first zero after the loss": when this loaded machine stalls the stand-in agents,
        # the watchdog zeroes 5 Hz robots 1 and 2 and their next command moves them again)
        moving = [r["t"] for r in rows[robot] if not is_zero(r)]
        stopped = [r["t"] for r in rows[robot] if is_zero(r) and r["t"] > max(moving)]
        assert stopped and stopped[0] - lost_at <= LOST_AFTER + SLACK, robot
    assert result["bridge_rc"] == 0, result["hw_log"]


def test_the_geofence_halts_every_robot(tmp_path):
    """Robot 3 is driven out of the arena (|x| ≤ 3.5 m) past the 0.3 m margin: geofence, zero
    to every robot, the robot stops outside, not far beyond the fence."""
    need_ros()
    case = {"kind": "bridge", "scenario": FLEET, "domain_id": unique_domain(), "args": AGE,
            "robots": {"3": {"pose": [-3.5, 0.0, 0.0]}},
            "steps": [{"do": "start"},
                      {"do": "stream", "s": 4.0, "rates": {"3": 100, "4": 100},
                       "goals": {"3": [-5.0, 0.0], "4": [1.5, 1.0]}},
                      {"do": "stop"}, {"do": "wait_exit", "s": 15}]}
    result = run_case(case, tmp_path, timeout=90)
    (event,) = events_of(result, "geofence")
    assert event["data"]["robot"] == 3 and event["data"]["x"] < -3.8
    x3 = result["robots_final"]["r3"][0]
    assert -4.0 < x3 < -3.8  # braked from 0.18 m/s within a few cm
    rows = by_robot(result["received"])
    assert is_zero(rows["3"][-1]) and is_zero(rows["4"][-1])


def test_another_domain_is_invisible_and_the_error_names_the_topics(tmp_path):
    need_ros()
    domain = unique_domain()
    case = {"kind": "bridge", "scenario": FLEET, "domain_id": domain, "lab_domain": domain + 1,
            "wait_mocap": 3, "steps": []}
    result = run_case(case, tmp_path, timeout=90)
    assert result["bridge_rc"] == 1
    assert "no pose within 3 s from robot 1: /vrpn_mocap/r1/pose" in result["hw_log"]
    assert result["received"] == []  # nothing crossed domains, not even the final zeros


def test_check_lists_the_graph_and_the_robots_timeouts(tmp_path):
    need_ros()
    case = {"kind": "check", "scenario": FLEET, "domain_id": unique_domain(),
            "robots": {"1": {"mocap_reliable": True}}}
    result = run_case(case, tmp_path, timeout=90)
    out = result["stdout"]
    assert result["returncode"] == 0, out + result["stderr"]
    assert "robot 1 mocap /vrpn_mocap/r1/pose [geometry_msgs/msg/PoseStamped]: 1 publishers — ok" \
        in out
    assert "/fake_r1  geometry_msgs/msg/PoseStamped  reliable/volatile" in out
    assert "/fake_r2  geometry_msgs/msg/PoseStamped  best_effort/volatile" in out
    assert "robot 4 cmd   /r4/cmd_vel [geometry_msgs/msg/TwistStamped]: 1 subscribers — ok" in out
    assert "robot 3 (/r3/cmd_vel): 0.3 s" in out
