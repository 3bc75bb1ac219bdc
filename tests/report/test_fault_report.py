"""The report's fault rows (tlfleet.coordinator.report.fault_table): detection and
clearance."""

from __future__ import annotations

import pytest
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.protocol.messages import Event
from tlfleet.coordinator.record.run_record import Detection
from tlfleet.coordinator.report.fault_table import fault_rows


def start(t, spec, kind, targets, wall=1000.0):
    return Event(t, "coordinator", "fault_start",
                 {"spec": spec, "kind": kind, "targets": targets, "wall": wall})


def end(t, spec, lasted):
    return Event(t, "coordinator", "fault_end", {"spec": spec, "lasted": lasted})


def test_a_cut_is_detected_by_the_coordinators_link_loss(scenarios_dir):
    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    spec = "cut:robot3@20+3"
    (row,) = fault_rows(scenario, [
        start(20.0, spec, "cut", ["agent-3"]),
        Event(20.6, "coordinator", "link_lost", {"process": "agent-3", "wall": 1000.55}),
        end(23.1, spec, 3.1)], None)
    assert row.detection.kind == "link_lost"
    assert row.detection.after_sim == pytest.approx(0.6)
    assert row.detection.after_wall == pytest.approx(0.55)
    assert row.min_clearance is None  # no trajectory


def test_a_partition_is_detected_by_its_targets_themselves(scenarios_dir):
    """Nobody loses the coordinator in a partition: the first target agent that notices it —
    stale mocap (at its last frame plus the silence) or a partner released — is the detection;
    an unrelated agent's report is not."""
    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    spec = "partition:robot2,sim@3+2"
    (row,) = fault_rows(scenario, [
        start(3.0, spec, "partition", ["agent-2", "sim"]),
        Event(3.0, "agent/1", "stale_mocap", {"silence": 0.1}),  # not a target
        Event(3.02, "agent/2", "stale_mocap", {"silence": 0.16}),
        end(5.0, spec, 2.0)], None)
    assert row.detection == Detection("stale_mocap", pytest.approx(3.18),
                                      pytest.approx(0.18), after_wall=None, by="agent/2")
    spec = "partition:robot3,robot4@36+6"
    (row,) = fault_rows(scenario, [
        start(36.0, spec, "partition", ["agent-3", "agent-4"]),
        Event(36.2, "agent/4", "collab_follow", {"requester": 3, "previous": -1}),  # a follow
        Event(36.35, "agent/4", "collab_follow", {"requester": -1, "previous": 3}),
        end(39.0, spec, 6.0)], None)
    assert row.detection.kind == "collab_follow"
    assert row.detection.after_sim == pytest.approx(0.35)
    (row,) = fault_rows(scenario, [start(36.0, spec, "partition", ["agent-3", "agent-4"]),
                                   end(39.0, spec, 6.0)], None)
    assert row.detection is None  # nobody noticed


def test_skipped_and_failed_faults_are_rows_with_their_reason(scenarios_dir):
    """A fault the run never reached and one the actuator could not inject are in the table,
    each saying why, not left out."""
    from tlfleet.coordinator.report.fault_table import render_fault_lines

    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    failed = Event(5.0, "coordinator", "fault_start",
                   {"spec": "kill:robot9@5", "kind": "kill", "targets": ["agent-9"],
                    "wall": 1000.0, "error": "no child agent-9"})
    skipped = Event(20.0, "coordinator", "fault_skipped",
                    {"spec": "cut:robot2@50+1", "kind": "cut", "targets": ["agent-2"],
                     "wall": 1001.0, "reason": "the run ended at t = 20.00 s, before the "
                                               "fault's time t = 50 s"})
    rows = fault_rows(scenario, [failed, skipped], None)
    assert [(r.spec, r.error) for r in rows] == [
        ("kill:robot9@5", "no child agent-9"),
        ("cut:robot2@50+1", "skipped: the run ended at t = 20.00 s, before the fault's time "
                            "t = 50 s")]
    assert rows[1].start_t is None and rows[1].detection is None
    lines = render_fault_lines(rows)
    assert any("`kill:robot9@5` (failed: no child agent-9)" in line for line in lines)
    assert any("`cut:robot2@50+1` (skipped: the run ended at t = 20.00 s" in line
               for line in lines)


def test_the_report_names_the_frames_it_lost():
    """Read off trajectory.csv itself: a gap between rows and an end that falls short."""
    import numpy as np
    from tlfleet.agent.stl.monitor import Trajectory
    from tlfleet.coordinator.record.run_record import LostFrames
    from tlfleet.coordinator.report.run_report import lost_frames

    t = np.concatenate([np.arange(0, 301) / 100, np.arange(500, 1321) / 100])  # 3.00 → 5.00
    traj = Trajectory(t=t, states={1: np.zeros((len(t), 3))})
    assert lost_frames(traj, duration=40.0, rate=100.0) == (
        LostFrames(3.0, 5.0, 199), LostFrames(13.2, 40.0, 2680))
    whole = Trajectory(t=np.arange(0, 4001) / 100, states={1: np.zeros((4001, 3))})
    assert lost_frames(whole, duration=40.0, rate=100.0) == ()
