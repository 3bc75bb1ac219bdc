"""Stage rules (§7.4), the collaboration protocol (§7.5) and the coupled sanity run of §11.7."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from stl_harness import authors_design, run_closed_loop
from tlfleet.agent.control.collision import CollisionParams
from tlfleet.agent.policy.stl import StepInput, single_agent
from tlfleet.agent.stl.funnel import Funnel
from tlfleet.agent.stl.messages import CollabRelease, CollabRequest, CollabUpdate, StatusAnnounce
from tlfleet.agent.stl.monitor import task_robustness
from tlfleet.agent.stl.recovery import RecoveryParams
from tlfleet.agent.stl.repair import ProtocolParams, choose_stage, stage2_enabled
from tlfleet.agent.stl.sequencer import build_sequence

PSI_3 = "dist(p3, [1.5,-1.5]) <= 0.1 & dist(p3, p4) <= 0.7"


def status(sender, c=0, kind="F", a=83.0, b=87.0, all_done=False):
    return StatusAnnounce(sender=sender, receiver=3, c=c, subtask=0, kind=kind, a=a, b=b,
                          all_done=all_done)


@pytest.fixture
def task3():
    (task,) = build_sequence(3, [f"F[57,58] ({PSI_3})"], stl_ids=[3, 4, 5])
    return task


def test_stage2_enabling_rule(task3):
    assert stage2_enabled(3, task3, 0, {4: status(4)})  # F deadline 87 > 58
    assert not stage2_enabled(3, task3, 3, {4: status(4)})  # already requesting
    assert not stage2_enabled(3, task3, 0, {})  # peer status unknown
    assert not stage2_enabled(3, task3, 0, {4: status(4, kind="F", a=40, b=50)})
    assert not stage2_enabled(3, task3, 0, {4: status(4, kind="G", a=21, b=90)})  # a_v < b_i
    assert stage2_enabled(3, task3, 0, {4: status(4, kind="G", a=60, b=90)})
    assert stage2_enabled(3, task3, 0, {4: status(4, c=-1, kind=None)})  # done
    assert stage2_enabled(3, task3, 0, {4: status(4, all_done=True, kind=None)})
    assert not stage2_enabled(3, task3, 0, {4: status(4, c=4)})  # v requesting itself
    (alone,) = build_sequence(5, ["F[44,47] (dist(p5, [-1,0.5]) <= 0.1)"])
    assert not stage2_enabled(5, alone, 0, {4: status(4)})  # V = {5}


def test_phase1_robot4_cannot_use_stage2():
    (task4,) = build_sequence(4, ["G[5,30] (dist(p4, p3) <= 1 & dist(p4, p5) <= 1)"])
    peers = {3: status(3, kind="G", a=21, b=30), 5: status(5, kind="G", a=21, b=30)}
    assert not stage2_enabled(4, task4, 0, peers)


def test_choose_stage():
    assert [choose_stage(ce, 2, 0, 3, True) for ce in (1, 2, 3)] == [1, 1, 2]
    assert choose_stage(3, 2, 0, 3, False) == 3
    assert choose_stage(5, 2, 3, 3, False) == 2  # repeat while c_i = i


def make_pair(latency_collision=None, recovery=None):
    lib_tasks = {
        3: build_sequence(3, [f"F[57,58] ({PSI_3})"], stl_ids=[3, 4]),
        4: build_sequence(4, ["F[83,87] (dist(p4, [2,2]) <= 0.1)"], stl_ids=[3, 4]),
    }
    library = {(j, t.index): t for j, seq in lib_tasks.items() for t in seq}
    col = latency_collision or CollisionParams(beta=0.0)
    extra = {} if recovery is None else {"recovery": recovery}
    a3 = single_agent(3, lib_tasks[3], library=library, peers=[4],
                      **authors_design(collision=col, **extra))
    a4 = single_agent(4, lib_tasks[4], library=library, peers=[3],
                      **authors_design(collision=col, **extra))
    return a3, a4, lib_tasks


def test_follower_adopts_updates_and_is_released():
    _, a4, tasks = make_pair()
    poses = {3: np.array([0.0, -2.0, 0.0]), 4: np.array([0.0, 0.0, 0.0])}
    s4, out = a4.step(a4.initial_state(), StepInput(30.0, poses))
    assert [type(m) for m in out.messages] == [StatusAnnounce]
    own = s4.funnel
    requested = Funnel.init("F", 57, 58, tasks[3][0].rho_opt, -1.5, 34.0)
    request = CollabRequest(sender=3, receiver=4, subtask=0, funnel=requested, c=3)
    s4, out = a4.step(s4, StepInput(34.0, poses, (request,)))
    assert s4.follow == 3 and s4.follow_funnel == requested
    assert out.log.follow == 3 and out.log.rho_max == requested.rho_max
    # the follower moves along −ε·∂ρ^{ψ_3}/∂x_4 (towards robot 3), F-hold does not apply
    assert out.u[1] < 0
    # a second requester is ignored (first come), an update of the followed one is adopted
    other = CollabRequest(sender=5, receiver=4, subtask=0, funnel=own, c=5)
    updated = requested.repair(3, requested.lower(35.0), 35.0)
    s4, _ = a4.step(s4, StepInput(35.0, poses, (other, CollabUpdate(3, 4, 0, updated))))
    assert s4.follow == 3 and s4.follow_funnel == updated
    # release: own funnel re-initialised now (t_r = 57), ce kept
    s4, out = a4.step(s4, StepInput(57.0, poses, (CollabRelease(3, 4, 0),)))
    assert s4.follow is None and s4.funnel.t_r == 57.0 and s4.funnel != own
    assert out.log.follow is None


def test_11_7_coupled_stage2_sequence():
    # the regression values of stl-funnel.md §11.7 are Algorithm 2 as published: no recovery
    a3, a4, tasks = make_pair(recovery=RecoveryParams(enabled=False))
    result = run_closed_loop([a3, a4], {3: (0.0, -2.0, 0.0), 4: (0.0, 0.0, 0.0)}, 60, start=30)
    ev3 = result.events(3)
    # agent 3: two stage-1 repairs then the stage-2 entry at ≈ 34.86 s
    assert [s for _, s in ev3[:3]] == [1, 1, 2]
    assert [t for t, _ in ev3[:3]] == pytest.approx([32.21, 33.56, 34.86], abs=0.05)
    requests = [(t, m) for t, m in result.messages if isinstance(m, CollabRequest)]
    assert len(requests) == 1 and requests[0][1].receiver == 4
    follow_times = [rec.t for rec in result.logs[4] if rec.follow == 3]
    assert follow_times[0] == pytest.approx(34.87, abs=0.05)  # one-step latency
    (o3,) = result.states[3].outcomes
    assert o3.satisfied and o3.t_done == pytest.approx(57.01, abs=0.05)
    rho3 = task_robustness(tasks[3][0], result.trajectory, smooth=True)
    assert rho3 == pytest.approx(0.0376, abs=1e-3) and rho3 >= o3.final_r
    assert o3.final_r == pytest.approx(-0.0144, abs=1e-3)
    releases = [t for t, m in result.messages if isinstance(m, CollabRelease)]
    assert releases == [o3.t_done]
    # agent 4 follows until the release, then runs its own F task: 2 × stage 1, then stage 3
    assert max(follow_times) == pytest.approx(o3.t_done, abs=0.02)
    ev4 = result.events(4)
    assert ev4[0][0] == pytest.approx(58.8, abs=0.1)
    assert [s for _, s in ev4[:2]] == [1, 1] and {s for _, s in ev4[2:]} == {3}
    (o4,) = result.states[4].outcomes
    assert o4.t_done == pytest.approx(83.0)
    rho4 = task_robustness(tasks[4][0], result.trajectory)
    assert rho4 == pytest.approx(-0.134, abs=2e-3) and rho4 >= o4.final_r and rho4 >= -0.4


def test_11_7_with_f_recovery_agent4_gets_back_its_original_r():
    """The same run with robustness recovery (tlfleet's default, tlfleet.agent.stl.recovery "F
    sub-tasks"): agent 3's story is unchanged (it requests help: c_3 = 3, no recovery); agent 4's
    stage-3 repairs lowered r for the funnel's front-loaded contraction, not for an infeasible
    task, so once it keeps up a recovery raises r back to r_0 = r_frac·ρ_max and φ''_4 ends
    above r_0 instead of at −0.134."""
    plain = run_closed_loop(list(make_pair(recovery=RecoveryParams(enabled=False))[:2]),
                            {3: (0.0, -2.0, 0.0), 4: (0.0, 0.0, 0.0)}, 60, start=30)
    a3, a4, tasks = make_pair()
    result = run_closed_loop([a3, a4], {3: (0.0, -2.0, 0.0), 4: (0.0, 0.0, 0.0)}, 60, start=30)
    assert result.events(3) == plain.events(3)
    assert result.states[3].outcomes == plain.states[3].outcomes
    (o4,) = result.states[4].outcomes
    (p4,) = plain.states[4].outcomes
    assert o4.events == p4.events and o4.recoveries >= 1
    recoveries = [rec for rec in result.logs[4] if rec.recovered]
    assert len(recoveries) == o4.recoveries and recoveries[-1].t < 83.0
    r0 = a4.cfg.funnel.r_frac * 0.09  # ρ_max = 0.9·ρ_opt at the re-initialisation
    assert recoveries[-1].r == pytest.approx(r0)
    rho4 = task_robustness(tasks[4][0], result.trajectory)
    # F-hold + first-instant completion (single_agent's defaults): done just above r_0
    assert o4.ended_by == "satisfaction" and r0 < rho4 < r0 + 1e-3
    assert rho4 > task_robustness(tasks[4][0], plain.trajectory) + 0.15
    assert o4.final_r == p4.final_r and rho4 >= o4.final_r  # r̄: the least r in force


def test_11_7_with_zero_latency_keeps_the_story():
    a3, a4, tasks = make_pair()
    result = run_closed_loop([a3, a4], {3: (0.0, -2.0, 0.0), 4: (0.0, 0.0, 0.0)}, 60, start=30,
                             latency_steps=0)
    assert [s for _, s in result.events(3)[:3]] == [1, 1, 2]
    (o3,) = result.states[3].outcomes
    assert o3.satisfied
    assert task_robustness(tasks[3][0], result.trajectory) > 0.02
    assert not math.isnan(result.states[4].outcomes[0].rho_phi)


def test_requester_ignores_requests_and_followers_detect_option():
    a3, a4, tasks = make_pair()
    poses = {3: np.array([0.0, -2.0, 0.0]), 4: np.array([0.0, 0.0, 0.0])}
    s3, _ = a3.step(a3.initial_state(), StepInput(30.0, poses))
    requesting = replace(s3, c=3)
    foreign = CollabRequest(sender=4, receiver=3, subtask=0, funnel=s3.funnel, c=4)
    after, _ = a3.step(requesting, StepInput(30.01, poses, (foreign,)))
    assert after.follow is None
    # followers_detect=True (the authors' code): a follower repairs its local copy, no messages
    lib = dict(a4.cfg.library)
    detecting = single_agent(4, tasks[4], library=lib, peers=[3], **authors_design(
        protocol=ProtocolParams(followers_detect=True, f_done_at_goal=False)))
    s4, _ = detecting.step(detecting.initial_state(), StepInput(30.0, poses))
    tight = Funnel.init("F", 57, 58, tasks[3][0].rho_opt, -1.3, 30.0)
    request = CollabRequest(sender=3, receiver=4, subtask=0, funnel=tight, c=3)
    s4, _ = detecting.step(s4, StepInput(40.0, poses, (request,)))  # ρ below the lower boundary
    assert s4.follow == 3 and s4.ce == 1 and s4.events == (1, 0, 0)
    assert s4.follow_funnel.t_r == 40.0
    plain, _ = a4.step(a4.step(a4.initial_state(), StepInput(30.0, poses))[0],
                       StepInput(40.0, poses, (request,)))
    assert plain.ce == 0 and plain.follow_funnel == tight  # default: followers do not detect


def test_status_is_announced_on_change_and_periodically():
    a3, a4, _ = make_pair()
    result = run_closed_loop([a3, a4], {3: (0.0, -2.0, 0.0), 4: (0.0, 0.0, 0.0)}, 5, start=30)
    times = [t for t, m in result.messages if isinstance(m, StatusAnnounce) and m.sender == 4]
    assert times == pytest.approx([30.0, 31.0, 32.0, 33.0, 34.0, 35.0])
    from3 = [(t, m.c) for t, m in result.messages
             if isinstance(m, StatusAnnounce) and m.sender == 3]
    assert from3[0] == (30.0, 0)
    assert any(c == 3 for _, c in from3)  # the stage-2 entry (c_3 = 3) is announced at once
