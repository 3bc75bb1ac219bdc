"""Recorder: the run directory files of architecture.md §6, on synthetic messages (no sockets)."""

from __future__ import annotations

import csv
import json
import math
from datetime import UTC

import numpy as np
import pytest
from tlfleet.agent.stl.monitor import read_trajectory_csv
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import encode
from tlfleet.bus.protocol.messages import Event, LtlStatus, MocapFrame, StlStatus
from tlfleet.coordinator.record.recorder import Recorder, RecorderTap
from tlfleet.coordinator.record.rundir import (
    LTL_STATUS_COLUMNS,
    STATUS_COLUMNS,
    STL_STATUS_COLUMNS,
    default_run_dir,
)


def frame(seq: int, ids=(1, 3), rate: float = 100.0) -> MocapFrame:
    t = seq / rate
    return MocapFrame(t, seq, tuple((r, r + t, -r * t, 0.1 * r) for r in ids))


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_trajectory_rows_after_start_only_strictly_increasing(tmp_path):
    rec = Recorder(tmp_path, [3, 1])
    rec.on_mocap(frame(0))  # before start: not a row
    rec.start()
    rec.on_mocap(frame(0))  # a late pre-start frame …
    rec.on_mocap(frame(0))  # … and tick 0 (the later one wins)
    for seq in (1, 2, 4, 3, 5, 2):  # 3 after 4 fills the gap it left; 2 again: stale
        rec.on_mocap(frame(seq))
    rec.close()
    traj = read_trajectory_csv(tmp_path / "trajectory.csv")
    assert traj.robot_ids == (1, 3)
    np.testing.assert_allclose(traj.t, [0.0, 0.01, 0.02, 0.03, 0.04, 0.05])
    np.testing.assert_allclose(traj.states[3][:, 0], 3 + traj.t)
    np.testing.assert_allclose(traj.states[1][:, 1], -traj.t)
    header = (tmp_path / "trajectory.csv").read_text().splitlines()[0]
    assert header == "t,x1,y1,th1,x3,y3,th3"
    assert rec.frames_written == 6 and rec.frames_skipped == 1


def test_frame_missing_a_robot_or_non_finite_is_skipped(tmp_path):
    rec = Recorder(tmp_path, [1, 3])
    rec.start()
    rec.on_mocap(frame(0))
    rec.on_mocap(MocapFrame(0.01, 1, ((1, 0.0, 0.0, 0.0),)))
    rec.on_mocap(MocapFrame(0.02, 2, ((1, math.nan, 0.0, 0.0), (3, 0.0, 0.0, 0.0))))
    rec.on_mocap(frame(3))
    rec.close()
    traj = read_trajectory_csv(tmp_path / "trajectory.csv")
    np.testing.assert_allclose(traj.t, [0.0, 0.03])


def test_files_are_flushed_while_the_run_goes(tmp_path):
    clock = FakeClock()
    rec = Recorder(tmp_path, [1, 3], flush_period=1.0, clock=clock)
    rec.start()
    for seq in range(50):
        rec.on_mocap(frame(seq))
    rec.on_event(Event(0.3, "sim", "contact", {"a": 1, "b": "wall"}))
    assert len((tmp_path / "trajectory.csv").read_text().splitlines()) == 1  # header only
    clock.now = 1.5
    rec.on_mocap(frame(50))  # a second has passed: everything so far is on disk
    lines = (tmp_path / "trajectory.csv").read_text().splitlines()
    assert len(lines) == 1 + 50
    assert json.loads((tmp_path / "events.jsonl").read_text())["kind"] == "contact"
    rec.close()


def test_status_and_event_rows(tmp_path):
    rec = Recorder(tmp_path, [1, 3])
    rec.on_status(StlStatus(3, 1.25, 1, 0.05, 0.1, -0.2, 0.08, 2, 1, 1, 4, (2, 1, 0)))
    rec.on_status(LtlStatus(1, 1.4, ("start", "a11"), ("a12", "a11"), "a12", (0, 2),
                            (("a11", 2), ("a12", 1)), 1, "navigate"))
    rec.on_event(Event(2.0, "agent/3", "repair", {"stage": 2, "r": 0.07}))
    rec.close()
    with open(tmp_path / "status.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert tuple(rows[0]) == STATUS_COLUMNS
    stl, ltl = rows
    assert (stl["t"], stl["robot"], stl["kind"], stl["subtask"], stl["stage"]) == \
        ("1.25", "3", "stl", "1", "2")
    # no JSON inside cells: lists are space-separated tokens, visits name:count
    assert float(stl["r"]) == 0.08 and stl["events"] == "2 1 0"
    assert ltl["kind"] == "ltl" and ltl["target"] == "a12"
    assert ltl["visits"] == "a11:2 a12:1"
    assert (ltl["prefix"], ltl["suffix"], ltl["buchi_states"]) == ("start a11", "a12 a11", "0 2")
    assert all(stl[c] == "" for c in LTL_STATUS_COLUMNS)  # the other kind's columns are blank
    assert all(ltl[c] == "" for c in STL_STATUS_COLUMNS)
    events = [json.loads(line) for line in (tmp_path / "events.jsonl").read_text().splitlines()]
    assert events == [{"t": 2.0, "source": "agent/3", "kind": "repair",
                       "data": {"stage": 2, "r": 0.07}}]


class CallbacksOnly:
    """A transport without ``subscribe_channel``: the tap queues samples from callbacks."""

    def __init__(self, inner):
        self.subscribe = inner.subscribe


@pytest.mark.parametrize("channels", [True, False], ids=["channels", "callbacks"])
def test_tap_decodes_in_the_loop_and_counts_malformed_payloads(tmp_path, channels):
    net = FakeNetwork()
    coord, sim = net.transport("coordinator"), net.transport("sim")
    rec = Recorder(tmp_path, [1, 3])
    tap = RecorderTap(coord if channels else CallbacksOnly(coord), "f", rec)
    assert len(tap._channels) == (3 if channels else 0)
    rec.start()
    sim.publish(keys.mocap("f"), encode(frame(0)))
    sim.publish(keys.mocap("f"), b"\xc1garbage")
    sim.publish(keys.mocap("f"), encode(Event(0.0, "x", "y", {})))  # wrong message kind
    sim.publish(keys.status("f", 3), b"")
    sim.publish(keys.event("f", "sim", 0), encode(Event(0.5, "sim", "sim_done", {})))
    sim.publish(keys.mocap("f"), encode(frame(1)))
    assert rec.frames_written == 0  # channels and callbacks only queue
    assert tap.drain(limit=2) == 2  # at most limit samples, the rest stays queued
    assert tap.drain() == 4
    tap.close()
    rec.close()
    assert dict(tap.malformed) == {"mocap": 2, "status": 1}
    assert rec.event_kinds["sim_done"] == 1 and rec.last_t == pytest.approx(0.01)
    assert len(read_trajectory_csv(tmp_path / "trajectory.csv").t) == 2


def test_default_run_dir_is_unique(tmp_path):
    from datetime import datetime

    now = datetime(2026, 11, 22, 5, 6, 7, tzinfo=UTC)
    first = default_run_dir("scenario1", tmp_path, now)
    assert first.name == "scenario1-20261122-050607"
    first.mkdir()
    assert default_run_dir("scenario1", tmp_path, now).name == "scenario1-20261122-050607-2"


def test_progress_bar_line():
    import io

    from tlfleet.cli.commands.run import ProgressBar

    wall = [0.0]
    stream = io.StringIO()
    bar = ProgressBar(stream, width=10, clock=lambda: wall[0])
    bar(45.0, 90.0)
    wall[0] = 0.1
    bar(45.05, 90.0)  # less than 0.1 s of sim time and 0.5 s of wall time later: not redrawn
    wall[0] = 2.0
    bar(55.0, 90.0)  # 10 s of sim time in 2 s of wall time: 5x, 35 s left = 7 s of wall time
    wall[0] = 3.0
    bar(55.0, 90.0)  # stalled: redrawn after 0.5 s of wall time, the rate falls
    wall[0] = 30.0
    bar(90.0, 90.0)
    bar.end()
    assert stream.getvalue().split("\r")[1:] == [
        "[#####     ] 45.0/90.0 s\x1b[K",
        "[######    ] 55.0/90.0 s  5.0x  ETA 0:07\x1b[K",
        "[######    ] 55.0/90.0 s  3.3x  ETA 0:10\x1b[K",
        "[##########] 90.0/90.0 s  1.3x  ETA 0:00\x1b[K\n",
    ]
