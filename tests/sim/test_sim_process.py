"""The simulator's loop on the fake transport (no sockets): both time modes of architecture.md §3,
deadline misses, dead agents, the watchdog, contacts, determinism and malformed payloads."""

from __future__ import annotations

import math
import threading
import time

import msgpack
import pytest
from sim_helpers import (
    FLEET,
    FakeAgent,
    Observer,
    SimRun,
    constant,
    distance,
    mission_frames,
    omni,
    poses_of,
    run_lockstep,
    scenario,
    unicycle,
)
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode, encode
from tlfleet.bus.protocol.messages import Clock, Command, MocapFrame
from tlfleet.sim.process import SimConfig, SimConfigError

STILL_OMNI = constant((0.0, 0.0, 0.0))


def test_initial_frame_is_repeated_until_start_and_nothing_moves():
    net = FakeNetwork()
    observer = Observer(net)
    agent = FakeAgent(net, 1, constant((0.2, 0.0, 0.0)))
    with SimRun(net, scenario(omni(1, 0.5, 0.5)), preview_period=0.02) as run:
        assert observer.wait_for(lambda: len(observer.frames) >= 3)
        assert all(f == MocapFrame(0.0, 0, ((1, 0.5, 0.5, 0.0),), ()) for f in observer.frames)
        assert agent.transport.network.alive_keys()[-1] == keys.alive(FLEET, "sim", 0)
        observer.send_control("stop")
        assert run.join() == 0
    assert observer.events_of("sim_done") == []
    assert keys.alive(FLEET, "sim", 0) not in net.alive_keys()  # token withdrawn on exit


def test_lockstep_mission_publishes_every_tick_with_the_due_robots():
    scen = scenario(unicycle(1, -1.0, 0.0), omni(2, 1.0, 0.0), duration=0.5)
    clocks: list[Clock] = []
    net = FakeNetwork()
    net.transport("clock").subscribe(keys.clock(FLEET),
                                     lambda k, p: clocks.append(decode(Clock, p)))
    observer = Observer(net)
    FakeAgent(net, 1, constant((0.3, 0.0)))
    FakeAgent(net, 2, constant((0.0, 0.2, 0.0)))
    with SimRun(net, scen) as run:
        observer.start_mission()
        assert run.join() == 0
    frames = mission_frames(observer.frames)
    assert [f.seq for f in frames] == list(range(51))
    assert [f.t for f in frames] == [k / 100 for k in range(51)]
    assert [(c.t, c.tick, c.mode) for c in clocks] == [(k / 100, k, "lockstep") for k in range(51)]
    expected_due = [(1, 2) if k % 20 == 0 else (2,) for k in range(50)] + [()]
    assert [f.due for f in frames] == expected_due
    assert [e.data for e in observer.events_of("sim_done")] == [{"ticks": 50}]
    assert observer.events_of("deadline_miss") == []
    # The commands moved the robots: unicycle 1 along +x at ≤ 0.3 m/s, omni 2 along +y.
    x1, y1, _ = frames[-1].pose(1)
    x2, y2, _ = frames[-1].pose(2)
    assert 0.05 < x1 + 1.0 <= 0.3 * 0.5 and y1 == pytest.approx(0.0, abs=1e-9)
    assert 0.05 < y2 <= 0.2 * 0.5 and x2 == pytest.approx(1.0, abs=1e-9)


def test_lockstep_does_not_advance_without_the_due_commands():
    net = FakeNetwork()
    observer = Observer(net)
    FakeAgent(net, 1, STILL_OMNI)
    silent = FakeAgent(net, 2, lambda frame, robot: None if frame.seq == 3 else (0.0, 0.0, 0.0))
    with SimRun(net, scenario(omni(1, 0, 0), omni(2, 1, 1), duration=0.1)) as run:
        observer.start_mission()
        assert observer.wait_for(lambda: observer.frames[-1].seq == 3)
        # Robot 2 owes tick 3: the sim must wait (the tick timeout is 2 s).
        assert not observer.wait_for(lambda: observer.frames[-1].seq > 3, timeout=0.3)
        silent.send(2, (0.0, 0.0, 0.0))  # a late answer for another tick does not count
        silent.send(4, (0.0, 0.0, 0.0))  # nor one from the future
        assert not observer.wait_for(lambda: observer.frames[-1].seq > 3, timeout=0.1)
        silent.send(3, (0.0, 0.0, 0.0))
        assert observer.wait_for(lambda: observer.frames[-1].seq > 3)
        assert run.join() == 0
    assert observer.events_of("deadline_miss") == []
    counts = {o.value: n for o, n in run.process.lockstep.counts.items()}
    assert counts["wrong_seq"] == 2


def test_tick_timeout_publishes_a_deadline_miss_and_goes_on():
    def late_at_2(frame: MocapFrame, robot: int):
        return None if frame.seq == 2 else (0.1, 0.0, 0.0)

    observer, run, _ = run_lockstep(scenario(omni(1, 0, 0), omni(2, 1, 1), duration=0.05),
                                    {1: STILL_OMNI, 2: late_at_2}, tick_timeout=0.2)
    misses = observer.events_of("deadline_miss")
    assert [(e.t, e.source, e.data) for e in misses] == [(0.02, "sim", {"robot": 2, "seq": 2})]
    assert run.process.stats.deadline_misses == 1
    assert run.process.lockstep.misses == {2: 1}
    (stats,) = observer.events_of("sim_stats")
    assert (stats.data["due"], stats.data["missed"], stats.data["deadline_misses"]) == (10, 1, 1)
    assert stats.data["commands"] == 9 and stats.data["latency_max_ms"] >= 0.0
    assert [f.seq for f in mission_frames(observer.frames)] == list(range(6))


def test_dead_agent_is_dropped_at_once_and_its_robot_stopped_by_the_watchdog():
    net = FakeNetwork()
    observer = Observer(net)
    FakeAgent(net, 1, STILL_OMNI)
    doomed = FakeAgent(net, 2, constant((0.2, 0.0, 0.0)))

    def die_at_50(frame: MocapFrame, robot: int):
        if frame.seq == 50:
            doomed.transport.kill()  # the process dies instead of answering tick 50
            return None
        return (0.2, 0.0, 0.0)

    doomed.policy = die_at_50
    scen = scenario(omni(1, 0, 0), omni(2, -2.0, 1.0), duration=1.5)
    with SimRun(net, scen, tick_timeout=30.0) as run:  # a wait for the dead would hang the test
        observer.start_mission()
        assert run.join() == 0
    frames = mission_frames(observer.frames)
    assert frames[50].due == (1, 2) and all(f.due == (1,) for f in frames[51:-1])
    assert observer.events_of("deadline_miss") == []
    stops = observer.events_of("watchdog_stop")
    # Last command applied at t = 0.49; stopped at the first tick more than 0.5 s later.
    assert [(e.t, e.data) for e in stops] == [(1.0, {"robot": 2, "last_command_t": 0.49})]
    xs = [p[0] for p in poses_of(frames, 2)]
    assert xs[100] - xs[50] > 0.09  # held its last command (zero-order hold) until then
    assert xs[-1] == pytest.approx(xs[-10], abs=1e-9)  # then came to rest
    assert max(xs) - (-2.0) < 0.2 * 1.0 + 0.01


def test_contact_events_through_the_process():
    scen = scenario(omni(1, 3.0, 0.0, max_lin=1.0), omni(2, -1.0, -2.0), omni(3, -0.5, -2.0),
                    duration=1.0)
    policies = {1: constant((1.0, 0.0, 0.0)), 2: constant((0.2, 0.0, 0.0)),
                3: constant((-0.2, 0.0, 0.0))}
    observer, _, _ = run_lockstep(scen, policies)
    contacts = sorted((e.data["a"], e.data["b"]) for e in observer.events_of("contact"))
    assert contacts == [(1, "wall"), (2, 3)]
    wall = next(e for e in observer.events_of("contact") if e.data["b"] == "wall")
    assert wall.data["what"] == "arena" and 0.0 < wall.t < 1.0
    frames = mission_frames(observer.frames)
    assert all(distance(f.pose(2), f.pose(3)) >= 0.4 - 0.005 for f in frames)


def _disturbed(seed: int | None = None, **config):
    scen = scenario(omni(1, 0, 0), unicycle(2, 1, 0), omni(3, 0.45, 0.05), duration=0.5,
                    disturbance=0.05, mocap_noise=0.01, seed=3)
    policies = {1: constant((0.2, 0.0, 0.0)), 2: constant((0.3, 0.5)),
                3: lambda frame, robot: (-0.2, 0.1 * math.sin(frame.t), 0.0)}
    if seed is not None:
        config["seed"] = seed
    observer, _, _ = run_lockstep(scen, policies, **config)
    payloads = observer.frame_bytes[-len(mission_frames(observer.frames)):]
    events = [(e.t, e.kind, e.data) for e in observer.events if e.kind != "sim_stats"]  # wall
    return payloads, events


def test_two_lockstep_runs_with_the_same_seed_are_identical():
    first, first_events = _disturbed(seed=9)
    second, second_events = _disturbed(seed=9)
    assert len(first) == 51
    assert first == second  # bit for bit, payload bytes
    assert first_events == second_events
    other, _ = _disturbed(seed=10)
    assert other != first


def test_max_speed_paces_a_lockstep_run_without_changing_it():
    free, free_events = _disturbed(seed=9)
    started = time.monotonic()
    paced, paced_events = _disturbed(seed=9, max_speed=2.0)
    wall = time.monotonic() - started
    assert paced == free  # bit for bit: pacing only adds waits
    assert paced_events == free_events
    assert wall >= 0.5 / 2.0 * 0.9  # 0.5 s of sim time at most twice as fast as wall time


def test_seed_defaults_to_the_scenarios():
    net = FakeNetwork()
    run = SimRun(net, scenario(omni(1, 0, 0), seed=42))
    assert run.process.config.seed == 0  # SimConfig's own default when built directly
    config = SimConfig.for_scenario(scenario(omni(1, 0, 0), seed=42))
    assert (config.seed, config.duration, config.mode) == (42, 1.0, "lockstep")


@pytest.mark.parametrize(("field", "value", "match"), [
    ("tick_timeout", 0.0, "tick_timeout = 0.0 s"), ("duration", -1.0, "duration = -1.0 s"),
    ("mode", "fast", "mode 'fast'"), ("poll", math.nan, "poll = nan"),
    ("max_speed", 0.0, "max_speed = 0.0"), ("max_speed", math.nan, "max_speed = nan"),
])
def test_bad_sim_settings_are_rejected(field, value, match):
    with pytest.raises(SimConfigError, match=match):
        SimConfig(**{field: value})


def test_malformed_payloads_are_counted_reported_and_survived():
    net = FakeNetwork()
    observer = Observer(net)
    agent = FakeAgent(net, 1, STILL_OMNI)
    rogue = net.transport("rogue")
    bad_cmd_key = keys.cmd(FLEET, 1)
    with SimRun(net, scenario(omni(1, 0, 0), duration=0.2)) as run:
        observer.wait_first_frame()
        rogue.publish(bad_cmd_key, b"\xc1 not msgpack")
        rogue.publish(bad_cmd_key, msgpack.packb({"v": 1, "k": "Command", "robot": "one"}))
        rogue.publish(bad_cmd_key, encode(Command(2, 0.0, 0, (0.0, 0.0, 0.0))))  # robot 2's
        rogue.publish(bad_cmd_key, encode(Command(1, 0.0, 0, (0.0, math.nan, 0.0))))
        rogue.publish(bad_cmd_key, encode(Command(1, 0.0, 0, (0.0, 0.0))))  # omni needs 3
        rogue.publish(keys.control(FLEET), b"")
        rogue.publish(keys.control(FLEET), encode(Clock(0.0, 0, "lockstep")))  # wrong kind
        rogue.publish(keys.control(FLEET), msgpack.packb({"v": 1, "k": "Control", "cmd": "go"}))
        assert observer.wait_for(lambda: len(observer.events_of("malformed_message")) == 2)
        observer.send_control("start")
        assert run.join() == 0  # ... and the mission ran to its end
    assert run.process.malformed == {bad_cmd_key: 5, keys.control(FLEET): 3}
    reports = {e.data["key"]: e.data["count"] for e in observer.events_of("malformed_message")}
    assert reports == {bad_cmd_key: 5, keys.control(FLEET): 3}
    assert observer.events_of("sim_done")
    assert len(agent.frames) > 20


def test_malformed_reports_are_rate_limited_per_key():
    net = FakeNetwork()
    observer = Observer(net)
    rogue = net.transport("rogue")
    with SimRun(net, scenario(omni(1, 0, 0)), malformed_report_period=60.0) as run:
        observer.wait_first_frame()
        rogue.publish(keys.cmd(FLEET, 1), b"junk")
        assert observer.wait_for(lambda: bool(observer.events_of("malformed_message")))
        for _ in range(49):
            rogue.publish(keys.cmd(FLEET, 1), b"junk")
        observer.send_control("stop")  # queued after the junk: the final count is reported
        assert run.join() == 0
    counts = [e.data["count"] for e in observer.events_of("malformed_message")]
    assert counts == [1, 50]  # the first at once, then nothing until the period or the end


def test_control_stop_ends_a_lockstep_run_early():
    net = FakeNetwork()
    observer = Observer(net)
    FakeAgent(net, 1, STILL_OMNI)
    FakeAgent(net, 2, lambda frame, robot: None if frame.seq >= 10 else (0.0, 0.0, 0.0))
    with SimRun(net, scenario(omni(1, 0, 0), omni(2, 1, 0), duration=100.0),
                tick_timeout=60.0) as run:
        observer.start_mission()
        assert observer.wait_for(lambda: observer.frames[-1].seq == 10)
        observer.send_control("stop")  # while the sim waits for robot 2
        assert run.join() == 0
    assert observer.events_of("sim_done") == []


def test_stop_event_ends_the_loop_like_a_signal():
    net = FakeNetwork()
    observer = Observer(net)
    run = SimRun(net, scenario(omni(1, 0, 0), duration=100.0)).start()
    observer.wait_first_frame()
    run.process.stop_event.set()
    assert run.join() == 0


def test_commands_before_start_are_ignored_unless_early_answers_to_tick_0():
    net = FakeNetwork()
    observer = Observer(net)
    agent = FakeAgent(net, 1, STILL_OMNI)
    with SimRun(net, scenario(omni(1, 0, 0), duration=0.1)) as run:
        observer.wait_first_frame()
        agent.send(5, (0.2, 0.0, 0.0))  # not an answer to the initial frame: ignored
        observer.send_control("start")
        assert run.join() == 0
    assert mission_frames(observer.frames)[-1].pose(1) == (0.0, 0.0, 0.0)
    counts = {o.value: n for o, n in run.process.lockstep.counts.items()}
    assert counts["before_start"] == 1 and "early" not in counts


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_an_agent_that_saw_start_first_and_answered_the_initial_frame_misses_nothing(mode):
    """The start message raced the sim: the agent took a preview frame (t = 0, seq = 0) for
    tick 0 and will not answer seq 0 again. Its answer must count for tick 0."""

    def once_per_seq(answered: set[int]):
        def policy(frame: MocapFrame, robot: int):
            if frame.seq in answered:
                return None
            answered.add(frame.seq)
            return (0.2, 0.0, 0.0)
        return policy

    def final_pose(race: bool):
        net = FakeNetwork()
        observer = Observer(net)
        agent = FakeAgent(net, 1, once_per_seq(set()), realtime_divider=1)
        with SimRun(net, scenario(omni(1, 0, 0), duration=0.1), mode=mode,
                    preview_period=0.01) as run:
            if race:
                agent.started = True  # as if its start message had arrived first
                assert observer.wait_for(lambda: len(observer.frames) >= 2)
            observer.start_mission()
            assert run.join() == 0
        stats = observer.events_of("sim_stats")[0].data
        assert stats["missed"] == 0 and observer.events_of("deadline_miss") == []
        assert stats["early"] == (1 if race else 0)
        return mission_frames(observer.frames)[-1].pose(1)

    raced = final_pose(race=True)
    assert raced[0] > 0.005  # moved from tick 0 on (0.2 m/s reached after 0.1 s)
    if mode == "lockstep":
        assert raced == final_pose(race=False)  # the race leaves no trace in the trajectory


def test_realtime_mode_paces_on_wall_time_with_empty_due():
    net = FakeNetwork()
    observer = Observer(net)
    agents = [FakeAgent(net, 1, constant((0.2, 0.0, 0.0)), realtime_divider=1),
              FakeAgent(net, 2, constant((0.3, 0.0)), realtime_divider=20)]
    scen = scenario(omni(1, 0, 0), unicycle(2, 0, 1), duration=0.3)
    with SimRun(net, scen, mode="realtime") as run:
        observer.wait_first_frame()
        started = time.monotonic()
        observer.send_control("start")
        assert run.join() == 0
        wall = time.monotonic() - started
    frames = mission_frames(observer.frames)
    assert [f.seq for f in frames] == list(range(31))
    assert all(f.due == () for f in frames)
    assert wall >= 0.3 * 0.9  # paced: never faster than real time
    assert 0.03 < frames[-1].pose(1)[0] <= 0.2 * 0.3
    assert 0.03 < frames[-1].pose(2)[0] <= 0.3 * 0.3
    assert len([f for f in agents[1].frames if f.seq % 20 == 0]) >= 2
    assert [e.kind for e in observer.events] == ["sim_stats", "sim_done"]
    stats = observer.events_of("sim_stats")[0].data
    # The fake agents answer inside the frame's publication: no deadline is missed. Deadlines
    # count from tick 1 (ticks 1..29 for robot 1, tick 20 for robot 2).
    assert (stats["mode"], stats["ticks"], stats["due"], stats["missed"]) == (
        "realtime", 30, 29 + 1, 0)


def test_sim_thread_leaves_no_thread_behind():
    before = threading.active_count()
    _, run, _ = run_lockstep(scenario(omni(1, 0, 0), duration=0.05), {1: STILL_OMNI})
    assert not run.thread.is_alive()
    assert threading.active_count() == before


def test_realtime_counts_missed_control_deadlines():
    net = FakeNetwork()
    observer = Observer(net)
    FakeAgent(net, 1, lambda frame, robot: (0.0, 0.0, 0.0) if frame.seq % 2 else None,
              realtime_divider=1)  # answers odd ticks only
    FakeAgent(net, 9, STILL_OMNI, realtime_divider=1)  # an agent of no robot: not counted
    with SimRun(net, scenario(omni(1, 0, 0), duration=0.1), mode="realtime") as run:
        observer.start_mission()
        assert run.join() == 0
    stats = observer.events_of("sim_stats")[0].data
    # ticks 1..9 are due (tick 0 looks like the preview frame); the even ones 2..8 are missed
    assert (stats["due"], stats["missed"], stats["commands"]) == (9, 4, 5)
    assert stats["missed_by_robot"] == {"1": 4}
    assert stats["ignored"] == {"unknown_robot": 10}


def test_lockstep_tick_0_waits_for_an_agent_the_sim_has_not_seen_yet():
    """Peer links: the start may reach the sim before an agent's liveliness token;
    the sim waits for every robot's agent before tick 0 (at most the tick timeout), so the
    late agent is due at tick 0 like the others."""
    net = FakeNetwork()
    observer = Observer(net)
    FakeAgent(net, 1, STILL_OMNI)
    with SimRun(net, scenario(omni(1, 0, 0), omni(2, 1, 1), duration=0.05)) as run:
        observer.start_mission()
        time.sleep(0.2)  # the sim has the start, not robot 2's token
        assert all(f.due == () for f in observer.frames) and run.process.stats.ticks == 0
        FakeAgent(net, 2, STILL_OMNI, started=True)
        assert run.join() == 0
    frames = mission_frames(observer.frames)
    assert frames[0].seq == 0 and frames[0].due == (1, 2)
    assert observer.events_of("deadline_miss") == []


def test_lockstep_starts_without_an_agent_that_never_comes_after_the_tick_timeout():
    observer, run, _ = run_lockstep(scenario(omni(1, 0, 0), omni(2, 1, 1), duration=0.03),
                                    {1: STILL_OMNI}, tick_timeout=0.2)
    frames = mission_frames(observer.frames)
    assert [f.due for f in frames] == [(1,), (1,), (1,), ()]
    assert run.process.stats.ticks == 3
