"""Offline and online monitors (standard and smooth semantics); trajectory CSV I/O and errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from tlfleet.agent.stl.monitor import (
    OnlineMonitor,
    Trajectory,
    TrajectoryFileError,
    read_trajectory_csv,
    sequence_robustness,
    task_robustness,
    write_trajectory_csv,
)
from tlfleet.agent.stl.parser import parse_task
from tlfleet.agent.stl.task import build_task


def line_trajectory() -> Trajectory:
    """Robot 1 moves from x = 0 to x = 10 at 1 m/s (t = 0 … 10 s, 1 Hz); robot 2 sits at x = 5."""
    t = np.arange(11.0)
    r1 = np.column_stack([t, np.zeros(11), np.zeros(11)])
    r2 = np.column_stack([np.full(11, 5.0), np.zeros(11), np.zeros(11)])
    return Trajectory(t, {1: r1, 2: r2})


def test_window_semantics_are_absolute_and_inclusive():
    traj = line_trajectory()
    # G[2,4] (x1 <= 3): samples t = 2, 3, 4 → min(3 − x) = 3 − 4 = −1
    assert task_robustness(parse_task("G[2,4] x1 <= 3"), traj) == -1.0
    assert task_robustness(parse_task("F[2,4] x1 <= 3"), traj) == 1.0
    assert task_robustness(parse_task("F[3,3] x1 >= 3"), traj) == 0.0
    # empty window: min/max over the empty set
    assert task_robustness(parse_task("G[3.2,3.8] x1 <= 0"), traj) == math.inf
    assert task_robustness(parse_task("F[20,30] x1 <= 0"), traj) == -math.inf


def test_standard_and_smooth_conjunction():
    traj = line_trajectory()
    phi = parse_task("G[0,10] (dist(p1, p2) <= 6 & x1 >= -1)")
    # ρ^ψ(t) = min(6 − |t − 5|, t + 1): smallest at t = 0: min(1, 1) = 1
    assert task_robustness(phi, traj) == pytest.approx(1.0)
    smooth = task_robustness(phi, traj, smooth=True)
    assert smooth == pytest.approx(1.0 - math.log(2) / 10)
    values, overall = sequence_robustness([parse_task("G[0,1] x1 <= 3"),
                                           parse_task("F[5,10] x1 >= 9.5")], traj)
    assert values == [2.0, 0.5] and overall == 0.5


def test_one_task_over_9001_samples_matches_scalar_evaluation():
    t = np.arange(9001) / 100.0
    rng = np.random.default_rng(3)
    states = {j: np.cumsum(rng.normal(0, 0.01, (9001, 3)), axis=0) for j in (3, 4, 5)}
    traj = Trajectory(t, states)
    task = build_task("G[5,30] (dist(p4, p3) <= 1 & dist(p4, p5) <= 1)", 4)
    offline = task_robustness(task, traj)
    mask = (t >= 5) & (t <= 30)
    d43 = np.hypot(*(states[4][:, :2] - states[3][:, :2]).T)
    d45 = np.hypot(*(states[4][:, :2] - states[5][:, :2]).T)
    assert offline == pytest.approx(np.min(np.minimum(1 - d43, 1 - d45)[mask]), abs=1e-12)


coords = st.floats(-3, 3, allow_nan=False)
tasks = st.sampled_from([
    "G[0.3,0.8] (dist(p1, [0,-2]) <= 0.5)",
    "F[0.2,0.6] (dist(p1, [1.5,-1.5]) <= 0.1 & dist(p1, p2) <= 0.7)",
    "G[0,1] (dist(p2 - p1, [sin(th1), -cos(th1)]) <= 0.1 & angdist(th2, th1) <= 0.09)",
    "F[0.5,0.5] !(x1 >= y2)",
])


@settings(max_examples=examples(150))
@given(text=tasks, smooth=st.booleans(),
       rows=st.lists(st.lists(coords, min_size=6, max_size=6), min_size=1, max_size=12))
def test_online_monitor_equals_offline_on_every_prefix(text, smooth, rows):
    phi = parse_task(text)
    data = np.array(rows)
    t = np.arange(len(rows)) / 10.0
    traj = Trajectory(t, {1: data[:, :3], 2: data[:, 3:]})
    online = OnlineMonitor(phi, smooth=smooth)
    for n in range(1, len(rows) + 1):
        value = online.update(t[n - 1], {1: data[n - 1, :3], 2: data[n - 1, 3:]})
        offline = task_robustness(phi, traj.prefix(n), smooth=smooth)
        if math.isinf(offline):
            assert value == offline
        else:
            assert value == pytest.approx(offline, rel=1e-12, abs=1e-12)


def test_csv_round_trip(tmp_path):
    traj = line_trajectory()
    path = tmp_path / "trajectory.csv"
    write_trajectory_csv(path, traj)
    assert path.read_text().splitlines()[0] == "t,x1,y1,th1,x2,y2,th2"
    back = read_trajectory_csv(path)
    assert np.array_equal(back.t, traj.t)
    assert all(np.array_equal(back.states[j], traj.states[j]) for j in (1, 2))


CSV_ERRORS = [
    ("", 1, 1, r"empty file"),
    ("time,x1,y1,th1\n0,0,0,0\n", 1, 1, r"first column must be 't', found 'time'"),
    ("t,x1,y1\n0,0,0\n", 1, 3, r"expected columns t followed by x<id>,y<id>,th<id> triples"),
    ("t,x1,y1,theta1\n0,0,0,0\n", 1, 4, r"expected column th<id>, found 'theta1'"),
    ("t,x1,y2,th1\n0,0,0,0\n", 1, 2, r"columns x1,y2,th1 must name one robot"),
    ("t,x2,y2,th2,x1,y1,th1\n0,0,0,0,0,0,0\n", 1, 5, r"robot ids must be ascending, 1 follows 2"),
    ("t,x1,y1,th1\n0,0,0,0\n0.1,0,abc,0\n", 3, 3, r"y1 is not a number: 'abc'"),
    ("t,x1,y1,th1\n0,0,0\n", 2, 4, r"expected 4 values, found 3"),
    ("t,x1,y1,th1\n0,0,0,nan\n", 2, 4, r"th1 is not finite"),
    ("t,x1,y1,th1\n", 2, 1, r"no samples after the header"),
    ("t,x1,y1,th1\n0,0,0,0\n1,0,0,0\n1,0,0,0\n", 4, 1, r"time must increase strictly"),
]


@pytest.mark.parametrize(("content", "line", "column", "message"), CSV_ERRORS)
def test_bad_csv_names_file_line_and_column(tmp_path, content, line, column, message):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(TrajectoryFileError, match=message) as info:
        read_trajectory_csv(path)
    assert (info.value.line, info.value.column) == (line, column)
    assert str(info.value).startswith(f"{path}:{line}:{column}: ")


def test_missing_csv_file(tmp_path):
    with pytest.raises(TrajectoryFileError, match="cannot open"):
        read_trajectory_csv(tmp_path / "nope.csv")
