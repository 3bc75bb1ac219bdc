"""``StepInput.unreachable`` (runtime knowledge of dead or silent peers, stl-funnel.md §7.4–§7.5):
forgotten announcements block stage 2; an unreachable requester releases its follower; a requester
whose helpers are all unreachable leaves stage 2."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from stl_harness import authors_design, run_closed_loop
from tlfleet.agent.control.collision import CollisionParams
from tlfleet.agent.policy.stl import StepInput, single_agent
from tlfleet.agent.stl.funnel import Funnel
from tlfleet.agent.stl.messages import CollabRelease, CollabRequest, CollabUpdate, StatusAnnounce
from tlfleet.agent.stl.sequencer import build_sequence

PSI_3 = "dist(p3, [1.5,-1.5]) <= 0.1 & dist(p3, p4) <= 0.7"
POSES = {3: np.array([0.0, -2.0, 0.0]), 4: np.array([0.0, 0.0, 0.0])}


def make_pair():
    tasks = {
        3: build_sequence(3, [f"F[57,58] ({PSI_3})"], stl_ids=[3, 4]),
        4: build_sequence(4, ["F[83,87] (dist(p4, [2,2]) <= 0.1)"], stl_ids=[3, 4]),
    }
    library = {(j, t.index): t for j, seq in tasks.items() for t in seq}
    col = CollisionParams(beta=0.0)
    return (single_agent(3, tasks[3], library=library, peers=[4],
                         **authors_design(collision=col)),
            single_agent(4, tasks[4], library=library, peers=[3],
                         **authors_design(collision=col)), tasks)


def test_an_unreachable_peer_is_forgotten_and_blocks_stage_2():
    """The §11.7 run: with peer 4 known, robot 3's third critical event is stage 2; with the same
    state but 4 unreachable at that step, it is stage 3 and no request goes out."""
    a3, a4, _ = make_pair()
    result = run_closed_loop([a3, a4], {3: (0.0, -2.0, 0.0), 4: (0.0, 0.0, 0.0)}, 4.85, start=30)
    s3 = result.states[3]
    assert 4 in s3.peers and s3.ce == 2
    poses = {j: result.trajectory.states[j][-1] for j in (3, 4)}  # the poses of t = 34.85
    known, out_known = a3.step(s3, StepInput(34.86, poses))
    gone, out_gone = a3.step(s3, StepInput(34.86, poses, unreachable=frozenset({4})))
    assert out_known.log.repair == 2 and known.c == 3
    assert any(isinstance(m, CollabRequest) for m in out_known.messages)
    assert out_gone.log.repair == 3 and gone.c == 0 and 4 not in gone.peers
    assert not any(isinstance(m, CollabRequest) for m in out_gone.messages)


def test_unreachable_ids_that_are_not_peers_change_nothing():
    a3, _, _ = make_pair()
    s3, _ = a3.step(a3.initial_state(), StepInput(30.0, POSES))
    s3 = replace(s3, peers={4: StatusAnnounce(4, 3, 0, 0, "F", 83.0, 87.0)})
    a, out_a = a3.step(s3, StepInput(30.01, POSES))
    b, out_b = a3.step(s3, StepInput(30.01, POSES, unreachable=frozenset({7})))
    assert a.peers == b.peers and out_a.u == out_b.u and a.c == b.c


def test_a_follower_releases_itself_when_its_requester_is_unreachable():
    _, a4, tasks = make_pair()
    s4, _ = a4.step(a4.initial_state(), StepInput(30.0, POSES))
    own = s4.funnel
    requested = Funnel.init("F", 57, 58, tasks[3][0].rho_opt, -1.5, 34.0)
    s4, _ = a4.step(s4, StepInput(34.0, POSES, (CollabRequest(3, 4, 0, requested, c=3),)))
    assert s4.follow == 3
    s4, out = a4.step(s4, StepInput(35.0, POSES, unreachable=frozenset({3})))
    assert s4.follow is None and out.log.follow is None
    assert s4.funnel.t_r == 35.0 and s4.funnel != own  # own funnel re-initialised, as on release


def test_a_requester_with_every_helper_unreachable_leaves_stage_2():
    a3, _, _ = make_pair()
    s3, _ = a3.step(a3.initial_state(), StepInput(30.0, POSES))
    requesting = replace(s3, c=3, announced=(3, s3.k, True))  # as after a stage-2 entry
    still, _ = a3.step(requesting, StepInput(30.01, POSES))
    left, out = a3.step(requesting, StepInput(30.01, POSES, unreachable=frozenset({4})))
    assert still.c == 3 and left.c == 0 and out.log.c == 0
    assert any(isinstance(m, StatusAnnounce) and m.c == 0 for m in out.messages)


def test_a_follower_that_released_itself_follows_its_requester_again_on_its_next_update():
    """Reachability is each agent's own view: robot 4 found robot 3 unreachable (a late reply)
    while robot 3 still counts on it and sends updates. Robot 4 follows again on the next update
    for the same sub-task once robot 3 is reachable; not while it is unreachable, not after
    robot 3 released it, and never on a stranger's update."""
    _, a4, tasks = make_pair()
    s4, _ = a4.step(a4.initial_state(), StepInput(30.0, POSES))
    requested = Funnel.init("F", 57, 58, tasks[3][0].rho_opt, -1.5, 34.0)
    s4, _ = a4.step(s4, StepInput(34.0, POSES, (CollabRequest(3, 4, 0, requested, c=3),)))
    released, _ = a4.step(s4, StepInput(35.0, POSES, unreachable=frozenset({3})))
    assert released.follow is None and released.orphaned == (3, 0)
    updated = replace(requested, r=requested.r - 0.2)
    update = CollabUpdate(3, 4, 0, updated)
    still_gone, _ = a4.step(released, StepInput(35.5, POSES, (update,), frozenset({3})))
    assert still_gone.follow is None and still_gone.orphaned == (3, 0)
    again, out = a4.step(still_gone, StepInput(37.0, POSES, (update,)))
    assert again.follow == 3 and again.follow_funnel == updated and out.log.follow == 3
    assert again.follow_subtask == 0 and again.orphaned is None
    other_subtask, _ = a4.step(released, StepInput(37.0, POSES, (CollabUpdate(3, 4, 1, updated),)))
    assert other_subtask.follow is None
    stranger, _ = a4.step(released, StepInput(37.0, POSES, (CollabUpdate(5, 4, 0, updated),)))
    assert stranger.follow is None
    let_go, _ = a4.step(released, StepInput(36.0, POSES, (CollabRelease(3, 4, 0),)))
    assert let_go.orphaned is None
    after, _ = a4.step(let_go, StepInput(37.0, POSES, (update,)))
    assert after.follow is None  # robot 3 released it: its late update means nothing
    # a new request (robot 3 asks again after a stage 3): followed, nobody orphaned any more
    anew = CollabRequest(3, 4, 0, requested, c=3)
    followed, _ = a4.step(released, StepInput(37.0, POSES, (anew,)))
    assert followed.follow == 3 and followed.orphaned is None
