"""The simulator publishes each frame on ``mocap`` and, for every control schedule
(divider d ≥ 2, phase φ) of the fleet, on ``mocap_every/<d>/<φ>`` when ``seq % d == φ``
(architecture.md §2)."""

from __future__ import annotations

import pytest
from sim_helpers import FLEET, FakeAgent, Observer, SimRun, constant, omni, scenario, unicycle
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode
from tlfleet.bus.protocol.messages import MocapFrame
from tlfleet.bus.transport import key_matches


def test_frame_keys_name_the_schedules_the_seq_falls_on():
    every = keys.mocap_every
    schedules = ((4, 0), (20, 0), (20, 10))
    assert keys.frame_keys(FLEET, 40, schedules) == (
        keys.mocap(FLEET), every(FLEET, 4), every(FLEET, 20))
    assert keys.frame_keys(FLEET, 8, schedules) == (keys.mocap(FLEET), every(FLEET, 4))
    assert keys.frame_keys(FLEET, 30, schedules) == (keys.mocap(FLEET), every(FLEET, 20, 10))
    assert keys.frame_keys(FLEET, 7, schedules) == (keys.mocap(FLEET),)
    assert keys.frame_schedules([(1, 0), (20, 10), (1, 0), (4, 0), (20, 0), (20, 10)]) == (
        (4, 0), (20, 0), (20, 10))
    assert every(FLEET, 20) == f"tlfleet/{FLEET}/mocap_every/20/0"
    assert every(FLEET, 20, 10) == f"tlfleet/{FLEET}/mocap_every/20/10"
    assert not key_matches(keys.mocap(FLEET), every(FLEET, 20))
    assert not key_matches(every(FLEET, 20), every(FLEET, 20, 10))
    with pytest.raises(ValueError, match="divider must be ≥ 2"):
        every(FLEET, 1)
    with pytest.raises(ValueError, match=r"phase must be in \[0, 20\), got 20"):
        every(FLEET, 20, 20)


def test_the_sim_publishes_the_due_frames_of_each_divider_on_its_key():
    scen = scenario(unicycle(1, -1.0, 0.0), omni(2, 1.0, 0.0), duration=0.5)

    net = FakeNetwork()
    every: list[MocapFrame] = []
    net.transport("ltl").subscribe(keys.mocap_every(FLEET, 20),
                                   lambda k, p: every.append(decode(MocapFrame, p)))
    observer = Observer(net)
    FakeAgent(net, 1, constant((0.3, 0.0)))
    FakeAgent(net, 2, constant((0.0, 0.2, 0.0)))
    with SimRun(net, scen) as run:
        observer.start_mission()
        assert run.join() == 0
    # the same payload as on mocap, every 20th mission frame (and the preview frames, seq 0)
    mission = [f for f in every if f.t > 0.0 or f.due]
    assert [f.seq for f in mission] == [0, 20, 40]
    assert all(f.seq == 0 for f in every if f not in mission)
    on_mocap = {f.seq: f for f in observer.frames if f.t > 0.0 or f.due}
    assert all(on_mocap[f.seq] == f for f in mission)
    published = {key for key, _ in net.published}
    assert keys.mocap_every(FLEET, 20) in published
    assert not any(key.startswith(f"tlfleet/{FLEET}/mocap_every/") and
                   key != keys.mocap_every(FLEET, 20) for key in published)


def test_staggered_ltl_robots_each_get_the_frames_of_their_phase():
    """Two LTL robots (phases 0 and 10 of 20): each schedule's key carries its own ticks."""
    scen = scenario(unicycle(1, -1.0, 0.0), unicycle(3, 1.0, 1.0), omni(2, 1.0, 0.0),
                    duration=0.5)
    net = FakeNetwork()
    got: dict[int, list[MocapFrame]] = {0: [], 10: []}
    for phase, frames in got.items():
        net.transport(f"ltl{phase}").subscribe(
            keys.mocap_every(FLEET, 20, phase),
            lambda k, p, frames=frames: frames.append(decode(MocapFrame, p)))
    observer = Observer(net)
    FakeAgent(net, 1, constant((0.0, 0.0)))
    FakeAgent(net, 3, constant((0.0, 0.0)))
    FakeAgent(net, 2, constant((0.0, 0.2, 0.0)))
    with SimRun(net, scen) as run:
        observer.start_mission()
        assert run.join() == 0
    mission = {phase: [f.seq for f in frames if f.t > 0.0 or f.due]
               for phase, frames in got.items()}
    assert mission == {0: [0, 20, 40], 10: [10, 30, 50]}  # the last frame (50) owes nothing
    # lockstep: robot 3 is listed as due exactly on its own ticks
    assert [f.seq for f in observer.frames if 3 in f.due] == [10, 30]
    assert [f.seq for f in observer.frames if 1 in f.due] == [0, 20, 40]
