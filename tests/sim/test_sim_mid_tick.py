"""Issue 17, ``SimParams.mid_tick`` (architecture.md §3): in realtime the frames of the robots
with control divider ≥ 2 (the LTL robots) are sampled half a mocap period after their tick and
published then, on their ``mocap_every`` keys only, so their agents compute while the every-tick
agents are idle; the physics of such a period is stepped in two parts with one disturbance
draw; an answer's latency counts from the frame it answers. Lockstep ignores the setting."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import pytest
from sim_helpers import FLEET, FakeAgent, Observer, SimRun, constant, omni, scenario, unicycle

from agent.protocol import keys
from agent.protocol.bounds import FleetBounds
from agent.protocol.codec import decode
from agent.protocol.messages import Command, MocapFrame
from bus.fake import FakeNetwork
from sim.process import SimConfig, SimProcess
from sim.world import World

PERIOD = 0.01  # [s] the helpers' mocap period (100 Hz)


def _every_frames(net: FakeNetwork, divider: int, phase: int) -> list[tuple[float, MocapFrame]]:
    """(wall time of arrival, frame) of everything published on ``mocap_every/d/φ``."""
    got: list[tuple[float, MocapFrame]] = []
    net.transport(f"every{phase}").subscribe(
        keys.mocap_every(FLEET, divider, phase),
        lambda k, p: got.append((time.monotonic(), decode(MocapFrame, p))))
    return got


class _MidAnswerer(FakeAgent):
    """An LTL agent reading its ``mocap_every`` key, answering each mission frame (stamped with
    the frame's own t, as agent.runtime.loop does)."""

    def __init__(self, network: FakeNetwork, robot: int, divider: int, phase: int):
        super().__init__(network, robot, constant((0.1, 0.0)), started=True)
        self.transport.subscribe(keys.mocap_every(FLEET, divider, phase), self._on_every)
        self.answered: list[MocapFrame] = []

    def _on_frame(self, _key: str, payload: bytes) -> None:  # not on mocap: its own key only
        pass

    def _on_every(self, _key: str, payload: bytes) -> None:
        frame = decode(MocapFrame, payload)
        if frame.t > 0.0:
            self.answered.append(frame)
            self.send(frame.seq, (0.1, 0.0), frame.t)


def _run_realtime(scen, duration: float):
    net = FakeNetwork()
    observer = Observer(net)
    every = _every_frames(net, 20, 0)
    ltl = _MidAnswerer(net, 1, 20, 0)
    FakeAgent(net, 2, constant((0.0, 0.2, 0.0)), realtime_divider=1)
    with SimRun(net, scen, mode="realtime") as run:
        observer.start_mission()
        assert run.join() == 0
    return observer, every, ltl


def test_realtime_ltl_frames_are_sampled_half_a_period_after_their_tick():
    scen = scenario(unicycle(1, -1.0, 0.0), omni(2, 1.0, 0.0), duration=0.45)
    observer, every, ltl = _run_realtime(scen, 0.45)
    mission = [f for _, f in every if f.t > 0.0]
    assert [f.seq for f in mission] == [0, 20, 40]
    assert [f.t for f in mission] == pytest.approx([0.005, 0.205, 0.405], abs=1e-12)
    assert all(f.due == () for f in mission)
    # mocap keeps the tick frames, at t_k, and never carries a mid-tick frame
    ticks = {f.seq: f for f in observer.frames if f.t > 0.0 or f.due}
    assert all(abs(f.t - f.seq * PERIOD) < 1e-12 for f in ticks.values())
    # the mid frame is a later sample than the tick frame: the omni robot moved in between
    for frame in mission[1:]:
        assert frame.pose(2)[1] > ticks[frame.seq].pose(2)[1]
        assert frame.pose(2)[1] < ticks[frame.seq + 1].pose(2)[1]
    # published between the ticks on the wall clock too: not before t_k + offset
    walls = [w for w, f in every if f.t > 0.0]
    assert walls[2] - walls[1] == pytest.approx(0.2, abs=0.05)
    stats = observer.events_of("sim_stats")[0].data
    # robot 1 answered its mid frames (tick 0 owes nothing); its latency counts from them
    # (the fake answers inside the publication), not from the tick frame 5 ms earlier
    assert (stats["due"] - 44, stats["missed"]) == (2, 0)  # robot 2: ticks 1..44
    assert stats["latency_p99_ms_by_robot"]["1"] < 3.0
    # every frame of a bounded run passes the fleet's plausibility check (t within half a
    # period of seq / rate)
    bounds = FleetBounds((-5.0, 5.0, -5.0, 5.0), 0.45, 100.0)
    assert all(bounds.frame_problem(f) is None for f in mission)


def test_without_mid_tick_the_ltl_frames_are_the_tick_frames():
    scen = scenario(unicycle(1, -1.0, 0.0), omni(2, 1.0, 0.0), duration=0.25)
    scen = replace(scen, sim=replace(scen.sim, mid_tick=False))
    observer, every, _ = _run_realtime(scen, 0.25)
    mission = [f for _, f in every if f.t > 0.0 or f.seq > 0]
    assert [(f.seq, f.t) for f in mission] == [(20, 0.2)]
    assert {f.seq: f for f in observer.frames}[20] == mission[0]


def test_a_period_in_two_parts_is_the_same_physics_with_one_disturbance_draw():
    """World.step(a) + step(b, draw_disturbance=False) = step(a + b) when a and b are whole
    physics sub-steps: the same positions to the last bit, the same random stream."""
    scen = scenario(omni(1, 0.0, 0.0), unicycle(2, 1.0, 1.0), disturbance=0.05)
    worlds = [World.from_scenario(scen, np.random.default_rng(7)) for _ in range(2)]
    for world in worlds:
        world.set_command(1, (0.3, -0.2, 0.5), 0.0)
        world.set_command(2, (0.4, 0.8), 0.0)
    for _ in range(20):
        worlds[0].step(PERIOD)
        worlds[1].step(0.005)
        worlds[1].step(PERIOD - 0.005, draw_disturbance=False)
    assert worlds[0].mocap_poses() == worlds[1].mocap_poses()
    assert worlds[0].rng.random() == worlds[1].rng.random()


def test_commands_taken_at_the_mid_tick_apply_from_it():
    """A command arriving after the mid-tick frame only drives the second part of the period,
    and the watchdog runs once, at t_k."""
    scen = scenario(unicycle(1, -1.0, 0.0), omni(2, 1.0, 0.0))
    sim = SimProcess(FakeNetwork().transport("sim"), scen, SimConfig(mode="realtime"))
    assert sim._mid_steps == 5 and sim._mid_offset == pytest.approx(0.005)
    assert sim._mid_keys(40) == (keys.mocap_every(FLEET, 20),) and sim._mid_keys(41) == ()
    sim._advance_to_mid(40, [Command(2, 0.40, 40, (0.1, 0.0, 0.0))])
    assert sim.world.robots[2].last_command_t == pytest.approx(0.40)
    sim._advance(40, [Command(1, 0.405, 40, (0.2, 0.0))], (1, 2))
    assert sim.world.robots[1].last_command_t == pytest.approx(0.405)
    assert sim.t == pytest.approx(0.41) and sim.world.time == pytest.approx(0.01)
    # lockstep (and realtime with mid_tick off) never splits a period
    assert SimProcess(FakeNetwork().transport("s"), scen, SimConfig())._mid_steps == 0
    off = replace(scen, sim=replace(scen.sim, mid_tick=False))
    assert SimProcess(FakeNetwork().transport("s"), off,
                      SimConfig(mode="realtime"))._mid_steps == 0
    # a fleet without a decimated robot has no mid-tick frames
    stl_only = scenario(omni(2, 1.0, 0.0))
    assert SimProcess(FakeNetwork().transport("s"), stl_only,
                      SimConfig(mode="realtime"))._mid_steps == 0


def test_the_plausibility_check_takes_a_mid_tick_time_and_no_later_one():
    bounds = FleetBounds((-5.0, 5.0, -5.0, 5.0), 100.0, 100.0)
    for seq in (1, 999, 8999):
        mid = seq / 100.0 + 0.005
        assert bounds.frame_problem(MocapFrame(mid, seq, (), ())) is None
        late = seq / 100.0 + 0.0051
        assert "does not match seq" in bounds.frame_problem(MocapFrame(late, seq, (), ()))
