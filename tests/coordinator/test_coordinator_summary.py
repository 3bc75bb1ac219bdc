"""Run summary on a synthetic run directory; robustness recomputed here with numpy min/max."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from tlfleet.coordinator.record.run_record import Contacts
from tlfleet.coordinator.report.summary import region_entries, summarise_run, write_summary

SCENARIO = """
name = "synthetic"
duration = 10.0
[[regions]]
name = "a1"
center = [-1.0, 0.0]
[[regions]]
name = "a2"
center = [1.0, 0.0]
[[robots]]
id = 1
kind = "unicycle"
pose = [-1.0, 0.0, 0.0]
ltl = "G F a1 & G F a2"
[[robots]]
id = 2
kind = "omni"
pose = [0.0, 1.0, 0.0]
stl = ["G[0,6] (dist(p2, p1) <= 0.8)"]
[[robots]]
id = 3
kind = "omni"
pose = [0.0, -2.0, 0.0]
stl = ["G[1,4] (dist(p3, [0,-2]) <= 0.8)", "F[6,9] (dist(p3, [2.5,-1.5]) <= 0.1)"]
"""


def synthetic_trajectory() -> tuple[np.ndarray, dict[int, np.ndarray]]:
    t = np.round(np.arange(0.0, 10.0 + 1e-9, 0.01), 2)
    # robot 1 oscillates between a1 and a2 (period 4 s): a1 at t = 0, 4, 8; a2 at t = 2, 6, 10
    x1 = -np.cos(np.pi * t / 2.0)
    p1 = np.column_stack([x1, np.zeros_like(t), np.zeros_like(t)])
    p2 = np.column_stack([x1 + 0.3 * np.sin(t), 0.5 + 0.4 * np.cos(3 * t), np.zeros_like(t)])
    p3 = np.column_stack([0.2 * np.sin(t) + 0.16 * t, -2.0 + 0.05 * t, np.zeros_like(t)])
    return t, {1: p1, 2: p2, 3: p3}


def write_run_dir(path, events=(), statuses=()) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    path.mkdir(parents=True, exist_ok=True)
    (path / "scenario.toml").write_text(SCENARIO, encoding="utf-8")
    t, states = synthetic_trajectory()
    with open(path / "trajectory.csv", "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["t", "x1", "y1", "th1", "x2", "y2", "th2", "x3", "y3", "th3"])
        for k in range(len(t)):
            writer.writerow([repr(float(t[k]))] + [repr(float(v)) for r in (1, 2, 3)
                                                   for v in states[r][k]])
    with open(path / "status.csv", "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["t", "robot", "kind", "subtask", "r", "events", "visits", "prefix",
                         "suffix", "rounds"])
        for row in statuses:
            writer.writerow(row)
    with open(path / "events.jsonl", "w", encoding="utf-8") as handle:
        for event in events:
            handle.write(json.dumps(event) + "\n")
        handle.write('{"t": 9.9, "source": "sim", "ki')  # torn last line of a crash
    (path / "run.json").write_text(json.dumps({"mode": "lockstep", "wall_time": 2.0,
                                               "malformed_received": {"mocap": 2}}))
    return t, states


EVENTS = [
    {"t": 1.0, "source": "sim", "kind": "contact", "data": {"a": 1, "b": 2}},
    {"t": 1.5, "source": "sim", "kind": "contact", "data": {"a": 3, "b": "wall"}},
    {"t": 2.0, "source": "sim", "kind": "deadline_miss", "data": {"robot": 2, "seq": 200}},
    {"t": 2.1, "source": "sim", "kind": "deadline_miss", "data": {"robot": 2, "seq": 210}},
    {"t": 2.2, "source": "sim", "kind": "deadline_miss", "data": {"robot": 3, "seq": 220}},
    {"t": 2.9, "source": "agent/3", "kind": "malformed_message", "data": {"key": "k", "count": 1}},
    {"t": 3.0, "source": "agent/3", "kind": "malformed_message", "data": {"key": "k", "count": 4}},
    {"t": 3.1, "source": "sim", "kind": "malformed_message", "data": {"key": "x"}},
    {"t": 3.5, "source": "agent/3", "kind": "repair", "data": {"stage": 1, "r": 0.1}},
    {"t": 3.6, "source": "agent/3", "kind": "repair", "data": {"stage": 3, "r": 0.0}},
    {"t": 3.7, "source": "agent/3", "kind": "repair", "data": {"stage": 3, "r": 0.0}},
    {"t": 4.0, "source": "sim", "kind": "watchdog_stop", "data": {"robot": 2}},
    {"t": 9.0, "source": "sim", "kind": "sim_stats",
     "data": {"due": 2000, "missed": 3, "latency_p50_ms": 0.41, "latency_p99_ms": 1.52}},
    {"t": 5.0, "source": "coordinator", "kind": "process_died",
     "data": {"process": "agent-2", "how": "exited with code -9", "returncode": -9}},
]
STATUSES = [
    (0.5, 3, "stl", 0, 0.3, "[0,0,0]", "", "", "", ""),
    (3.9, 3, "stl", 0, 0.12, "[1,0,2]", "", "", "", ""),
    (7.0, 3, "stl", 1, 0.07, "[0,0,0]", "", "", "", ""),
    (8.0, 1, "ltl", "", "", "", '[["a1",3],["a2",2]]', '["start","a1"]', '["a2","a1"]', 2),
]


def test_stl_robustness_recomputed_independently(tmp_path):
    t, s = write_run_dir(tmp_path, EVENTS, STATUSES)
    _text, summary = summarise_run(tmp_path)
    w = (t >= 0) & (t <= 6)
    rho2 = np.min(0.8 - np.hypot(*(s[2][w, :2] - s[1][w, :2]).T))
    w1, w2 = (t >= 1) & (t <= 4), (t >= 6) & (t <= 9)
    rho3a = np.min(0.8 - np.hypot(s[3][w1, 0] - 0.0, s[3][w1, 1] + 2.0))
    rho3b = np.max(0.1 - np.hypot(s[3][w2, 0] - 2.5, s[3][w2, 1] + 1.5))
    assert summary.stl[2].robustness == pytest.approx(rho2, abs=1e-12)
    sub = summary.stl[3].subtasks
    assert [x.robustness for x in sub] == pytest.approx([rho3a, rho3b], abs=1e-12)
    assert summary.stl[3].robustness == pytest.approx(min(rho3a, rho3b), abs=1e-12)
    assert rho3b < 0 < rho3a  # the synthetic data makes the two signs differ


def test_repairs_ltl_contacts_deadlines_deaths(tmp_path):
    write_run_dir(tmp_path, EVENTS, STATUSES)
    text, summary = summarise_run(tmp_path)
    sub = summary.stl[3].subtasks
    assert [x.r_last for x in sub] == [0.12, 0.07]
    assert sub[0].repairs_status == (1, 0, 2)
    assert summary.stl[3].repair_events == {1: 1, 3: 2}
    assert summary.stl[2].subtasks[0].r_last is None
    ltl = summary.ltl[1]
    assert ltl.visits_reported == {"a1": 3, "a2": 2} and ltl.rounds == 2
    assert ltl.plan_regions == ("a1", "a2") and ltl.all_plan_regions_visited
    # robot 1 is at a1 at t = 0, 4, 8 and at a2 at t = 2, 6, 10
    assert ltl.visits_trajectory == {"a1": 3, "a2": 3}
    assert summary.contacts == Contacts(robot_robot=1, robot_wall=1,
                                        pairs={"1-2": 1, "3-wall": 1})
    d = summary.deadlines
    assert d.deadline_miss == 3 and d.deadline_miss_by_robot == {"2": 2, "3": 1}
    assert d.malformed == 4 + 1 + 2 and d.watchdog_stop == 1
    assert [x.process for x in summary.process_deaths] == ["agent-2"]
    for needle in ("robot 3: rho = ", "a1 3/3", "robot-robot 1, robot-wall 1", "3 missed",
                   "malformed messages: 7", "process deaths: 1", "agent-2",
                   "3 of 2000 missed (0.150 %)", "p99 1.52 ms"):
        assert needle in text


def test_closest_approach(tmp_path):
    _t, s = write_run_dir(tmp_path)
    _text, summary = summarise_run(tmp_path)
    gaps = {(i, j): np.hypot(*(s[i][:, :2] - s[j][:, :2]).T) - 0.4
            for i, j in ((1, 2), (1, 3), (2, 3))}
    pair = min(gaps, key=lambda p: gaps[p].min())
    assert summary.closest_approach.pair == pair
    assert summary.closest_approach.gap == pytest.approx(gaps[pair].min())


def test_missing_or_broken_trajectory_is_reported_not_raised(tmp_path):
    write_run_dir(tmp_path)
    (tmp_path / "trajectory.csv").write_text("t,x1,y1,th1\n")
    text, summary = write_summary(tmp_path)
    assert "no samples" in summary.trajectory_error
    assert summary.stl[2].robustness is None
    assert (tmp_path / "summary.txt").read_text().startswith("run synthetic")
    assert json.loads((tmp_path / "summary.json").read_text())["frames"] == 0
    assert "trajectory:" in text


@pytest.mark.parametrize(("d", "expected"), [
    ([1.0, 0.2, 0.1, 0.2, 1.0], 1),
    ([0.1, 1.0, 0.1], 2),                 # starting inside counts
    ([1.0, 0.2, 0.27, 0.2, 0.31, 0.2], 2),  # 0.27 is within the hysteresis: same visit
    ([1.0, 0.5, 0.26], 0),
])
def test_region_entries(d, expected):
    xy = np.column_stack([np.asarray(d), np.zeros(len(d))])
    assert region_entries(xy, (0.0, 0.0), 0.25) == expected
    assert math.isfinite(float(len(d)))
