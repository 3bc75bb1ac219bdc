"""Issue 17: the simulator publishes each frame on ``mocap`` and, for every control divider d ≥ 2
of the fleet, on ``mocap_every/<d>`` when ``seq % d == 0`` (architecture.md §2)."""

from __future__ import annotations

import pytest
from sim_helpers import FLEET, FakeAgent, Observer, SimRun, constant, omni, scenario, unicycle

from agent.protocol import keys
from agent.protocol.codec import decode
from agent.protocol.messages import MocapFrame
from bus.fake import FakeNetwork


def test_frame_keys_name_the_dividers_that_divide_the_seq():
    assert keys.frame_keys(FLEET, 40, (4, 20)) == (
        keys.mocap(FLEET), keys.mocap_every(FLEET, 4), keys.mocap_every(FLEET, 20))
    assert keys.frame_keys(FLEET, 8, (4, 20)) == (keys.mocap(FLEET), keys.mocap_every(FLEET, 4))
    assert keys.frame_keys(FLEET, 7, (4, 20)) == (keys.mocap(FLEET),)
    assert keys.frame_dividers([1, 20, 1, 4, 20]) == (4, 20)
    assert keys.mocap_every(FLEET, 20) == f"tlfleet/{FLEET}/mocap_every/20"
    assert not keys.key_matches(keys.mocap(FLEET), keys.mocap_every(FLEET, 20))
    with pytest.raises(ValueError, match="divider must be ≥ 2"):
        keys.mocap_every(FLEET, 1)


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
