"""Per-sub-task verdicts, held fractions and stationary episodes
(tlfleet.coordinator.report.task_verdicts)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tlfleet.agent.scenario import parse_scenario
from tlfleet.agent.stl.monitor import Trajectory
from tlfleet.bus.protocol.messages import Event
from tlfleet.coordinator.record.run_record import SubtaskVerdict, Verdicts
from tlfleet.coordinator.report.task_verdicts import (
    held_fraction,
    render_lines,
    stationary_episodes,
    verdict,
)


@pytest.mark.parametrize("op,rho,t_end,expected,by", [
    ("G", 0.05, 100.0, "satisfied", None),
    ("G", -0.3, 100.0, "violated", 0.3),
    ("G", 0.05, 50.0, "not evaluated", None),  # a run cut short: no "met" for G[10,100]
    ("G", math.inf, 5.0, "not evaluated", None),  # no sample in the window at all
    ("F", 0.02, 50.0, "satisfied", None),  # F already satisfied inside the covered part
    ("F", -0.2, 50.0, "not evaluated", None),
    ("F", -0.2, 100.0, "violated", 0.2),
])
def test_verdict(op, rho, t_end, expected, by):
    v = verdict(op, 10.0, 100.0, rho, t_end)
    assert v.verdict == expected
    assert v.by == (pytest.approx(by) if by is not None else None)


SCENARIO = parse_scenario({
    "name": "mini", "duration": 20.0,
    "regions": [{"name": "a1", "center": [1.0, 1.0]}],
    "robots": [
        {"id": 1, "kind": "unicycle", "pose": [0.0, 0.0, 0.0], "ltl": "F a1"},
        {"id": 2, "kind": "omni", "pose": [0.0, -1.0, 0.0],
         "stl": ["G[0,20] (dist(p2, p1) <= 0.5)"]},
    ],
})


def _traj(x2: np.ndarray, x1: np.ndarray | None = None) -> Trajectory:
    t = np.arange(len(x2)) * 0.1
    s1 = np.zeros((len(t), 3))
    if x1 is not None:
        s1[:, 0] = x1
    s2 = np.zeros((len(t), 3))
    s2[:, 0] = x2
    s2[:, 1] = -0.0
    return Trajectory(t, {1: s1, 2: s2})


def test_held_fraction_counts_the_window_samples_where_psi_holds():
    x2 = np.concatenate([np.full(150, 0.3), np.full(51, 2.0)])  # 150 of 201 samples within 0.5
    traj = _traj(x2)
    assert held_fraction("G[0,20] (dist(p2, p1) <= 0.5)", traj, 20.0) == pytest.approx(150 / 201)
    assert held_fraction("G[0,10] (dist(p2, p1) <= 0.5)", traj, 20.0) == 1.0
    assert held_fraction("G[30,40] (dist(p2, p1) <= 0.5)", traj, 20.0) is None


def test_stationary_episodes_flag_a_robot_that_stands_while_its_task_wants_motion():
    n = 201
    x1 = np.linspace(0.0, 4.0, n)  # the LTL robot drives all the time: never flagged
    x2 = np.full(n, -1.0)  # the STL robot stands 1 m .. 5 m away (ρ^ψ < −0.1): flagged
    episodes = stationary_episodes(SCENARIO, _traj(x2, x1), [])
    assert [e.robot for e in episodes] == [2]
    assert episodes[0].t_start == pytest.approx(0.0)
    assert episodes[0].t_end == pytest.approx(20.0)
    # close enough (ρ^ψ ≥ −0.1) it may stand; the LTL robot parked after plan_finished may too
    still = np.zeros(n)
    events = [Event(0.0, "agent/1", "plan_finished", {})]
    assert stationary_episodes(SCENARIO, _traj(still + 0.55, still), events) == []
    flagged = stationary_episodes(SCENARIO, _traj(still + 0.55, still), [])
    assert [e.robot for e in flagged] == [1]


def test_waiting_for_the_right_of_way_is_no_stationary_episode_up_to_its_limit():
    """An LTL robot standing inside a ``yield`` (begin/end events) waits, not stalls — up to
    15 s; a longer wait, a stand outside the yield, or after the yield ended is flagged."""
    t = np.arange(201) * 0.1
    # robot 1 drives, stands from 4 s to 16 s, drives on; the STL robot 2 keeps 0.2 m beside it
    # (its task holds: it is never flagged)
    x1 = np.where(t < 4.0, t * 0.1, np.where(t < 16.0, 0.4, 0.4 + (t - 16.0) * 0.1))
    traj = Trajectory(t, {1: np.stack([x1, np.zeros(201), np.zeros(201)], axis=1),
                          2: np.stack([x1 + 0.2, np.zeros(201), np.zeros(201)], axis=1)})
    yielded = [Event(4.0, "agent/1", "yield", {"state": "begin", "other": 2}),
               Event(16.0, "agent/1", "yield", {"state": "end", "other": 2})]
    assert stationary_episodes(SCENARIO, traj, yielded) == []
    stalled = stationary_episodes(SCENARIO, traj, [])
    assert [e.robot for e in stalled] == [1]
    assert stalled[0].t_start == pytest.approx(4.0, abs=0.6)
    # a yield shorter than the stand does not cover it
    short = [Event(4.0, "agent/1", "yield", {"state": "begin", "other": 2}),
             Event(8.0, "agent/1", "yield", {"state": "end", "other": 2})]
    assert [e.robot for e in stationary_episodes(SCENARIO, traj, short)] == [1]
    # nor does one beyond the limit (a 30 s stand inside a 30 s yield)
    long_t = np.arange(401) * 0.1
    x_long = np.where(long_t < 4.0, long_t * 0.1, np.where(long_t < 34.0, 0.4,
                                                            0.4 + (long_t - 34.0) * 0.1))
    long_traj = Trajectory(long_t, {1: np.stack([x_long, np.zeros(401), np.zeros(401)], axis=1),
                                    2: np.stack([x_long + 0.2, np.zeros(401), np.zeros(401)],
                                                axis=1)})
    long_yield = [Event(4.0, "agent/1", "yield", {"state": "begin", "other": 2}),
                  Event(34.0, "agent/1", "yield", {"state": "end", "other": 2})]
    assert [e.robot for e in stationary_episodes(SCENARIO, long_traj, long_yield)] == [1]


def test_render_lines_name_the_switches():
    v = Verdicts(coupling_aware=False, coupling_share=0.9, recovery=True, recoveries={"3": 2},
                 subtasks={3: (SubtaskVerdict("violated", by=0.25, held=0.5, label="φ3"),)},
                 stationary=())
    text = "\n".join(render_lines(v))
    assert "coupling-aware leaders off" in text and "2 recoveries" in text
    assert "φ3 violated by 0.250, held 50 %" in text
