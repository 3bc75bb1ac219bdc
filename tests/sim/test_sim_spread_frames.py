"""Issue 17, ``SimParams.spread_frames`` (architecture.md §3): in realtime each robot's frames are
sampled at its own offset within the mocap period (``Scenario.frame_offset``) and published
then, on ``mocap_at/<s>`` (every-tick robots, s ≥ 1) or its ``mocap_every`` key (divider ≥ 2,
mid-tick), so the agents compute one after another instead of all at once; the physics of a
period is stepped in parts with one disturbance draw; an answer's latency counts from the frame
it answers and its deadline is one period after that frame. Lockstep publishes the tick's frame
on every key."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from sim_helpers import (
    FLEET,
    FakeAgent,
    Observer,
    SimRun,
    constant,
    omni,
    run_lockstep,
    scenario,
    unicycle,
)
from tlfleet.agent.runtime.loop import AgentLoop, LoopConfig
from tlfleet.agent.scenario.loader import load_scenario
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.bounds import FleetBounds
from tlfleet.bus.protocol.codec import decode
from tlfleet.bus.protocol.messages import Command, MocapFrame
from tlfleet.bus.transport import key_matches
from tlfleet.coordinator.security.policy import fleet_grants
from tlfleet.sim.lockstep import due_robots
from tlfleet.sim.process import SimConfig, SimProcess
from tlfleet.sim.stats import TimingStats
from tlfleet.sim.world import World

ROOT = Path(__file__).resolve().parents[2]
PERIOD = 0.01  # [s] the helpers' mocap period (100 Hz); 10 physics steps of 1 ms


def _fleet():
    """LTL robot 1 (divider 20, offset 6), STL robots 2 (offset 0) and 3 (offset 3)."""
    return scenario(unicycle(1, -1.0, 0.0), omni(2, 1.0, 0.0), omni(3, 0.0, 1.5), duration=0.45)


def test_frame_offsets_spread_the_every_tick_robots_and_put_the_ltl_robots_mid_tick():
    s1 = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    assert s1.substeps_per_tick == 10
    assert [s1.frame_offset(r.id) for r in s1.robots] == [7, 7, 0, 2, 5]
    assert s1.every_tick_offsets() == (2, 5)  # the mocap_at keys (the LTL robots' 7 is not one)
    off = replace(s1, sim=replace(s1.sim, spread_frames=False))
    assert [off.frame_offset(r.id) for r in off.robots] == [0] * 5
    assert off.every_tick_offsets() == ()
    coarse = replace(s1, sim=replace(s1.sim, physics_rate=100.0))  # one physics step a tick
    assert [coarse.frame_offset(r.id) for r in coarse.robots] == [0] * 5
    many = scenario(*(omni(i, 0.5 * i, 0.0) for i in range(1, 31)))
    # 30 slots share sim.frame_slots = 5 instants, six consecutive robots each
    assert [many.frame_offset(i) for i in range(1, 31)] == [2 * (i // 6) for i in range(30)]
    assert many.every_tick_offsets() == (2, 4, 6, 8)
    ten = replace(many, sim=replace(many.sim, frame_slots=10))  # one instant a physics step
    assert [ten.frame_offset(i) for i in range(1, 31)] == [i // 3 for i in range(30)]
    assert [_fleet().frame_offset(i) for i in (1, 2, 3)] == [6, 0, 3]
    alone = scenario(omni(1, 0.0, 0.0), unicycle(2, 1.0, 1.0))  # one slot each: mid-tick
    assert [alone.frame_offset(i) for i in (1, 2)] == [0, 5]
    with pytest.raises(KeyError):
        s1.frame_offset(9)


@pytest.mark.parametrize("n_stl, n_ltl", [(3, 2), (4, 0), (5, 0), (6, 1), (12, 2), (30, 0),
                                          (29, 3)])
@pytest.mark.parametrize("frame_slots", [1, 2, 3, 5, 7, 10])
def test_frame_slots_bound_the_instants_and_share_them_evenly(n_stl, n_ltl, frame_slots):
    """``sim.frame_slots`` = K: at most K distinct offsets; the every-tick robots in id order
    keep their order and fill the instants evenly (group sizes differ by at most one, the LTL
    robots' shared slot counting as one member of the last); a fleet with at most K slots has
    the offsets it had without the bound."""
    robots = [unicycle(i, -3.0 + 0.5 * i, -2.0) for i in range(1, n_ltl + 1)]
    robots += [omni(n_ltl + j, -3.0 + 0.3 * j, 1.0) for j in range(1, n_stl + 1)]
    bounded = scenario(*robots)
    bounded = replace(bounded, sim=replace(bounded.sim, frame_slots=frame_slots))
    free = replace(bounded, sim=replace(bounded.sim, frame_slots=10 ** 6))
    offsets = {r.id: bounded.frame_offset(r.id) for r in bounded.robots}
    slots = n_stl + (n_ltl > 0)
    if slots <= frame_slots:
        assert offsets == {r.id: free.frame_offset(r.id) for r in free.robots}
    assert len(set(offsets.values())) <= min(frame_slots, slots)
    every = [offsets[n_ltl + j] for j in range(1, n_stl + 1)]
    assert every == sorted(every) and every[0] == 0
    members = every + ([offsets[1]] if n_ltl else [])
    assert all(offsets[i] == offsets[1] for i in range(1, n_ltl + 1))  # the LTL robots' slot
    if n_ltl:
        assert offsets[1] == max(offsets.values())  # is the last
    sizes = sorted(members.count(o) for o in set(members))
    assert sizes[-1] - sizes[0] <= 1, sizes


def test_frame_keys_by_offset():
    assert keys.mocap_at(FLEET, 3) == f"tlfleet/{FLEET}/mocap_at/3"
    with pytest.raises(ValueError, match="offset must be ≥ 1"):
        keys.mocap_at(FLEET, 0)
    assert keys.robot_frames(FLEET, 1, 0, 0) == keys.mocap(FLEET)
    assert keys.robot_frames(FLEET, 1, 0, 6) == keys.mocap_at(FLEET, 6)
    assert keys.robot_frames(FLEET, 20, 10, 5) == keys.mocap_every(FLEET, 20, 10)
    assert not key_matches(keys.mocap(FLEET), keys.mocap_at(FLEET, 3))


class _KeyAnswerer(FakeAgent):
    """An agent reading only ``key``, answering each mission frame there with a command stamped
    with the frame's own t (as tlfleet.agent.runtime.loop does), or silent."""

    def __init__(self, network: FakeNetwork, robot: int, key: str, silent: bool = False):
        super().__init__(network, robot, constant((0.0, 0.0)), started=True)
        self.got: list[tuple[float, MocapFrame]] = []
        self.silent = silent
        self.transport.subscribe(key, self._on_key)

    def _on_frame(self, _key: str, payload: bytes) -> None:  # not mocap: its own key only
        pass

    def _on_key(self, _key: str, payload: bytes) -> None:
        frame = decode(MocapFrame, payload)
        self.got.append((time.monotonic(), frame))
        if frame.t > 0.0 and not self.silent:
            u = (0.1, 0.0) if self.robot == 1 else (0.0, 0.2, 0.0)
            self.send(frame.seq, u, frame.t)


def _run(scen, *, silent: tuple[int, ...] = (), mode: str = "realtime"):
    net = FakeNetwork()
    observer = Observer(net)
    agents = {1: _KeyAnswerer(net, 1, keys.mocap_every(FLEET, 20, 0), 1 in silent),
              2: _KeyAnswerer(net, 2, keys.mocap(FLEET), 2 in silent),
              3: _KeyAnswerer(net, 3, keys.mocap_at(FLEET, 3), 3 in silent)}
    with SimRun(net, scen, mode=mode) as run:
        observer.start_mission()
        assert run.join() == 0
    return observer, agents, run.process.timing


def test_realtime_frames_are_sampled_at_each_robots_offset():
    observer, agents, timing = _run(_fleet())
    ticks = {f.seq: f for f in observer.frames if f.t > 0.0 or f.due}
    assert sorted(ticks) == list(range(1, 46))  # (tick 0 looks like the preview frame)
    assert all(abs(f.t - f.seq * PERIOD) < 1e-12 for f in ticks.values())  # mocap: the ticks
    at3 = [f for _, f in agents[3].got if f.t > 0.0]
    assert [f.seq for f in at3] == list(range(45))  # the last tick (45) ends the run
    assert [f.t for f in at3] == pytest.approx([k * PERIOD + 0.003 for k in range(45)],
                                               abs=1e-12)
    ltl = [f for _, f in agents[1].got if f.t > 0.0]
    assert [(f.seq, round(f.t, 9)) for f in ltl] == [(0, 0.006), (20, 0.206), (40, 0.406)]
    # a frame sampled 3 steps after tick k lies between the tick frames k and k + 1
    for frame in at3[1:]:
        y = frame.pose(2)[1]
        assert ticks[frame.seq].pose(2)[1] < y < ticks[frame.seq + 1].pose(2)[1]
    # the offset frames go out between the ticks on the wall clock too
    walls = [w for w, f in agents[3].got if f.t > 0.0]
    ltl_walls = {f.seq: w for w, f in agents[1].got if f.t > 0.0}
    assert ltl_walls[20] > walls[20]  # tick 20: robot 3's frame (3 ms) before robot 1's (6 ms)
    assert 0.3 < (walls[40] - walls[10]) / 0.3 < 1.5
    stats = observer.events_of("sim_stats")[0].data
    # deadlines: robot 2 ticks 1..44; robot 3 ticks 1..43 (tick 44's closes after the end);
    # robot 1 ticks 20 and 40. The fake answers inside the publication: nothing is missed, and
    # each latency counts from the frame answered, not from the tick frame 3 or 6 ms before
    # (from the tick, robot 3's latencies would be about 3 ms and robot 1's about 6 ms: below
    # half of that, with a margin for the tick frame going out late). The median and the least,
    # not the tail: one preemption of the sim's thread on a loaded machine makes a single
    # latency long (this test, then with p99 < 3 ms for both, failed once at load 20; the
    # failing line was not captured). Counting from the tick frame fails these (checked).
    assert (stats["due"], stats["missed"]) == (44 + 43 + 2, 0)
    assert len(timing.robot_latencies[3]) >= 43 and len(timing.robot_latencies[1]) >= 2
    assert timing.robot_latencies[3].percentile(50) < 0.0015
    assert timing.robot_latencies[1].min < 0.003
    bounds = FleetBounds((-5.0, 5.0, -5.0, 5.0), 0.45, 100.0)
    assert all(bounds.frame_problem(f) is None for f in at3 + ltl)


def test_a_silent_agent_at_an_offset_misses_each_deadline_once():
    observer, _, _ = _run(_fleet(), silent=(3,))
    stats = observer.events_of("sim_stats")[0].data
    assert stats["missed_by_robot"] == {"3": 43}
    assert stats["missed"] == 43


def test_without_spread_frames_every_key_carries_the_tick_frames():
    scen = _fleet()
    scen = replace(scen, sim=replace(scen.sim, spread_frames=False))
    net = FakeNetwork()
    observer = Observer(net)
    ltl = _KeyAnswerer(net, 1, keys.mocap_every(FLEET, 20, 0))
    FakeAgent(net, 2, constant((0.0, 0.2, 0.0)), realtime_divider=1)
    FakeAgent(net, 3, constant((0.0, 0.2, 0.0)), realtime_divider=1)
    with SimRun(net, scen, mode="realtime") as run:
        observer.start_mission()
        assert run.join() == 0
    assert [(f.seq, f.t) for _, f in ltl.got if f.t > 0.0] == [(20, 0.2), (40, 0.4)]
    assert keys.mocap_at(FLEET, 3) not in {key for key, _ in net.published}


def test_lockstep_publishes_the_tick_frame_on_every_offset_key():
    net_frames: list[MocapFrame] = []

    def policy(frame, robot):
        return (0.1, 0.0) if robot == 1 else (0.0, 0.1, 0.0)

    scen = replace(_fleet(), duration=0.25)
    net = FakeNetwork()
    net.transport("at3").subscribe(keys.mocap_at(FLEET, 3),
                                   lambda k, p: net_frames.append(decode(MocapFrame, p)))
    observer = Observer(net)
    for robot in (1, 2, 3):
        FakeAgent(net, robot, policy)
    with SimRun(net, scen) as run:
        observer.start_mission()
        assert run.join() == 0
    on_mocap = {f.seq: f for f in observer.frames if f.t > 0.0 or f.due}
    mission = [f for f in net_frames if f.t > 0.0 or f.due]
    assert [f.seq for f in mission] == list(range(26))
    assert all(on_mocap[f.seq] == f for f in mission)  # the same frame, due list included
    # and a lockstep run's trajectory does not depend on the setting
    off = replace(scen, sim=replace(scen.sim, spread_frames=False))
    a, _, _ = run_lockstep(scen, {r: policy for r in (1, 2, 3)})
    b, _, _ = run_lockstep(off, {r: policy for r in (1, 2, 3)})
    assert a.frame_bytes == b.frame_bytes


def test_a_period_in_parts_is_the_same_physics_with_one_disturbance_draw():
    """World.step(3 dt) + step(3 dt) + step(4 dt) without new draws = step(10 dt): the same
    poses to the last bit and the same random stream."""
    scen = scenario(omni(1, 0.0, 0.0), unicycle(2, 1.0, 1.0), disturbance=0.05)
    worlds = [World.from_scenario(scen, np.random.default_rng(7)) for _ in range(2)]
    for world in worlds:
        world.set_command(1, (0.3, -0.2, 0.5), 0.0)
        world.set_command(2, (0.4, 0.8), 0.0)
    step = PERIOD / 10
    for _ in range(20):
        worlds[0].step(PERIOD)
        worlds[1].step(3 * step)
        worlds[1].step(3 * step, draw_disturbance=False)
        worlds[1].step(PERIOD - 6 * step, draw_disturbance=False)
    assert worlds[0].mocap_poses() == worlds[1].mocap_poses()
    assert worlds[0].rng.random() == worlds[1].rng.random()


def test_commands_apply_from_the_part_they_arrived_in_and_deadlines_follow_the_offset():
    sim = SimProcess(FakeNetwork().transport("sim"), _fleet(), SimConfig(mode="realtime"))
    assert sim._spread and sim._step == pytest.approx(0.001)
    assert sim._sub_ticks(40) == [(3, (keys.mocap_at(FLEET, 3),)),
                                  (6, (keys.mocap_every(FLEET, 20),))]
    assert sim._sub_ticks(41) == [(3, (keys.mocap_at(FLEET, 3),))]
    sim._advance_part(40, 3, [Command(2, 0.40, 40, (0.0, 0.1, 0.0))])
    assert sim.world.robots[2].last_command_t == pytest.approx(0.40)
    sim._advance_part(40, 6, [Command(3, 0.403, 40, (0.0, 0.2, 0.0))])
    assert sim.world.robots[3].last_command_t == pytest.approx(0.403)
    assert sim.world.time == pytest.approx(0.006)
    sim._advance(40, [Command(1, 0.406, 40, (0.1, 0.0))], (1, 2, 3))
    assert sim.world.robots[1].last_command_t == pytest.approx(0.406)
    assert sim.t == pytest.approx(0.41) and sim.world.time == pytest.approx(0.01)
    # robot 2 (offset 0) closes with the next frame; robot 3 at t_41 + 3 ms, robot 1 + 6 ms
    assert sim._unreported[:2] == (40, (2,))
    assert list(sim._deadlines) == [(pytest.approx(0.413), 40, (3,)),
                                    (pytest.approx(0.416), 40, (1,))]
    sim.timing.answered(3, 40)
    sim._close_deadlines(0.4125)
    assert sim.timing.missed == 0 and len(sim._deadlines) == 2
    sim._close_deadlines(0.416)
    assert (sim.timing.missed, sim.timing.missed_by_robot, list(sim._deadlines)) == (
        1, {1: 1}, [])
    # lockstep, and realtime without the setting, never split a period
    assert not SimProcess(FakeNetwork().transport("s"), _fleet(), SimConfig())._spread
    off = replace(_fleet(), sim=replace(_fleet().sim, spread_frames=False))
    assert not SimProcess(FakeNetwork().transport("s"), off, SimConfig(mode="realtime"))._spread


def test_the_shared_ticks_are_those_a_slow_robot_is_due_on():
    """``SimProcess._shared_tick`` (the split of ``sim_stats``) is ``due_robots``' rule over the
    robots with divider ≥ 2: Scenario 1's two LTL robots at staggered phases, one LTL robot,
    and a fleet of every-tick robots, which has no shared tick."""
    fleets = (load_scenario(ROOT / "scenarios" / "scenario1.toml"), _fleet(),
              scenario(*(omni(i, 0.5 * i, 0.0) for i in range(1, 31))))
    for fleet in fleets:
        sim = SimProcess(FakeNetwork().transport("sim"), fleet, SimConfig(mode="realtime"))
        expected = [any(sim.dividers[r] > 1
                        for r in due_robots(k, sim.dividers, sim.dividers, sim.phases))
                    for k in range(200)]
        assert [sim._shared_tick(k) for k in range(200)] == expected
        assert any(expected) == any(d > 1 for d in sim.dividers.values())


def test_the_split_asks_once_per_tick_whether_it_is_shared():
    """30 robots answering every tick: ``shared`` is evaluated once per tick, not per answer
    (a 30-robot, 60 s run's summary spent 2 s asking 180 000 times)."""
    asked: list[int] = []
    stats = TimingStats(every_tick=range(1, 31),
                        shared=lambda seq: asked.append(seq) or seq % 10 == 4)
    for seq in range(50):
        stats.frame_published(seq, seq * 0.01)
        for robot in range(1, 31):
            stats.command_arrived(robot, seq, seq * 0.01 + (0.003 if seq % 10 == 4 else 0.001))
    summary = stats.summary()
    assert sorted(asked) == list(range(50))
    assert summary["latency_p99_ms_shared"] == pytest.approx(3.0)
    assert summary["latency_p99_ms_alone"] == pytest.approx(1.0)


def test_latency_counts_from_the_frame_at_the_commands_offset():
    stats = TimingStats(keep_frames=2)
    stats.frame_published(7, 10.000)
    stats.frame_published(7, 10.005, offset=5)
    stats.command_arrived(2, 7, 10.002)
    stats.command_arrived(3, 7, 10.006, offset=5)
    assert {r: s.values() for r, s in stats.robot_latencies.items()} == \
        {2: [pytest.approx(0.002)], 3: [pytest.approx(0.001)]}
    stats.frame_published(9, 10.020)  # forgets tick 7, both of its frames
    stats.command_arrived(3, 7, 10.021, offset=5)
    assert len(stats.robot_latencies[3]) == 1


def test_the_plausibility_check_takes_a_frame_up_to_one_period_after_its_tick():
    bounds = FleetBounds((-5.0, 5.0, -5.0, 5.0), 100.0, 100.0)
    for seq in (1, 999, 8999):
        tick = seq / 100.0
        for ok in (tick, tick + 0.005, tick + 0.009, tick - 0.005):
            assert bounds.frame_problem(MocapFrame(ok, seq, (), ())) is None, (seq, ok)
        for bad in (tick + 0.0101, tick - 0.0051):
            assert "does not match seq" in bounds.frame_problem(MocapFrame(bad, seq, (), ()))


def test_an_agent_at_an_offset_reads_its_offset_key_and_the_acl_grants_it():
    fake = FakeNetwork()
    loop = AgentLoop(fake.transport("a"), LoopConfig(FLEET, 5, decimated=True, offset=6),
                     object(), None)
    assert loop._keys["mocap"] == keys.mocap_at(FLEET, 6)
    plain = AgentLoop(fake.transport("b"), LoopConfig(FLEET, 5, offset=6), object(), None)
    assert plain._keys["mocap"] == keys.mocap(FLEET)  # test doubles read every frame
    with pytest.raises(ValueError, match="offset must be ≥ 0"):
        LoopConfig(FLEET, 5, offset=-1)
    s1 = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    grants = {g.identity: g for g in fleet_grants(s1)}
    fleet = s1.fleet
    assert keys.mocap_at(fleet, 2) in grants["sim"].publish
    assert keys.mocap_at(fleet, 5) in grants["sim"].publish
    assert keys.mocap_at(fleet, 2) in grants["robot4"].subscribe
    assert keys.mocap(fleet) not in grants["robot4"].subscribe
    assert keys.mocap_at(fleet, 5) in grants["robot5"].subscribe
    assert keys.mocap(fleet) in grants["robot3"].subscribe
    assert not any("mocap_at" in key for key in grants["robot3"].subscribe)
