"""The STL agent loop on the fake network: no logic in the loop, stage 2 over query/reply, and a
dead partner (stl-funnel.md §7.4–§7.5, §11.7; architecture.md §3)."""

from __future__ import annotations

import threading
import time
from dataclasses import replace

import numpy as np
import pytest
from runtime_helpers import FakeClock, FakeSim, stl_loop
from stl_harness import authors_design, run_closed_loop
from tlfleet.agent.control.collision import CollisionParams
from tlfleet.agent.policy.stl import (
    LogRecord,
    StepInput,
    StlAgent,
    build_agents,
    single_agent,
    status_readers,
)
from tlfleet.agent.runtime import stl_agent
from tlfleet.agent.runtime.config import AgentConfig
from tlfleet.agent.scenario import load_scenario
from tlfleet.agent.stl.messages import CollabRelease, CollabRequest
from tlfleet.agent.stl.sequencer import build_sequence
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.messages import StlStatus

RATE = 100.0
DT = 1.0 / RATE
PSI_3 = "dist(p3, [1.5,-1.5]) <= 0.1 & dist(p3, p4) <= 0.7"
FLEET = "pair"


def make_pair():
    """§11.7's set-up (as tests/stl/test_stl_collaboration.py): no collision avoidance."""
    tasks = {
        3: build_sequence(3, [f"F[57,58] ({PSI_3})"], stl_ids=[3, 4]),
        4: build_sequence(4, ["F[83,87] (dist(p4, [2,2]) <= 0.1)"], stl_ids=[3, 4]),
    }
    library = {(j, t.index): t for j, seq in tasks.items() for t in seq}
    col = CollisionParams(beta=0.0)
    a3 = single_agent(3, tasks[3], library=library, peers=[4], **authors_design(collision=col))
    a4 = single_agent(4, tasks[4], library=library, peers=[3], **authors_design(collision=col))
    return a3, a4


def drive(sim, loops, poses, k0, steps, *, before_tick=None):
    """Lockstep: frame k (every live loop due) → each loop answers → integrate like the pure
    harness (x += Δt·u). Returns the poses per tick."""
    trajectory = []
    for step in range(steps + 1):
        k = k0 + step
        t = k / RATE
        if before_tick is not None:
            before_tick(t, loops)
        trajectory.append({j: p.copy() for j, p in poses.items()})
        live = {loop.config.robot: loop for loop in loops if not loop.stopped}
        sim.frame(t, k, poses, due=sorted(live))
        for loop in live.values():
            assert loop.run_once(0.0)
        if step == steps:
            break
        for j in live:
            poses[j] = poses[j] + DT * np.asarray(sim.command(j, k).u)
    return trajectory


def test_one_agent_commands_equal_the_pure_step():
    """Scenario 1's robot 5 alone in the loop: every command equals a direct StlAgent.step on the
    same poses, status at 10 Hz of sim time (the loop adds no logic)."""
    scenario = load_scenario("scenarios/scenario1.toml")
    network = FakeNetwork()
    sim = FakeSim(network, scenario.fleet)
    loop, _ = stl_loop(network, scenario.fleet, build_agents(scenario, robots=[5])[5])
    direct = build_agents(scenario, robots=[5])[5]
    state = direct.initial_state()
    poses = {r.id: np.array(r.pose, dtype=float) for r in scenario.robots}
    sim.control("start")
    n = 800  # 8 s: the G[21,30] funnel of robot 5 is active and steering from t = 0
    moved = 0.0
    for k in range(n):
        t = k / RATE
        sim.frame(t, k, poses, due=[5])
        assert loop.run_once(0.0)
        state, out = direct.step(state, StepInput(t, {j: p.copy() for j, p in poses.items()}))
        u = sim.command(5, k).u
        assert u == pytest.approx(out.u, abs=0.0)
        poses[5] = poses[5] + DT * np.asarray(u)
        moved += abs(u[0]) + abs(u[1])
    assert moved > 0.5  # it did steer
    statuses = [s for s in sim.statuses if isinstance(s, StlStatus)]
    assert len(statuses) == pytest.approx(n / 10, abs=1)
    assert all(s.robot == 5 for s in statuses)
    assert loop.stats.steps == n
    # robot 4, the one reader of its announcements, is absent: they failed, 4 counts as
    # unreachable (robot 3 reads none of robot 5's, so it was never asked)
    assert loop.link.unreachable == frozenset({4})


def test_two_agents_reproduce_stage2_of_the_pure_harness():
    """§11.7 over query/reply: same repair times and stages, same request time and the same
    trajectory as ``run_closed_loop`` with one-step message latency."""
    a3, a4 = make_pair()
    start, duration = 30.0, 28.0  # through robot 3's completion and release at 57.01 s
    reference = run_closed_loop([a3, a4], {3: (0.0, -2.0, 0.0), 4: (0.0, 0.0, 0.0)}, duration,
                                start=start, latency_steps=1)
    ref_requests = [t for t, m in reference.messages if isinstance(m, CollabRequest)]
    assert ref_requests == [pytest.approx(34.86, abs=0.05)]

    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loops = [stl_loop(network, FLEET, a)[0] for a in make_pair()]
    poses = {3: np.array([0.0, -2.0, 0.0]), 4: np.array([0.0, 0.0, 0.0])}
    sim.control("start")
    trajectory = drive(sim, loops, poses, round(start * RATE), round(duration * RATE))

    repairs = [(e.t, e.data["stage"]) for e in sim.events
               if e.kind == "repair" and e.source == "agent/3"]
    assert repairs == [pytest.approx(x) for x in reference.events(3)]
    assert [s for _, s in repairs] == [1, 1, 2]
    requests = [e for e in sim.events if e.kind == "collab_request"]
    assert [e.t for e in requests] == pytest.approx(ref_requests)
    assert requests[0].data["receivers"] == [4]
    follows = [e for e in sim.events if e.kind == "collab_follow"]
    assert follows[0].source == "agent/4" and follows[0].data["requester"] == 3
    assert follows[0].t == pytest.approx(ref_requests[0] + DT)  # one-step latency
    releases = [e for e in sim.events if e.kind == "collab_release"]
    ref_releases = [t for t, m in reference.messages if isinstance(m, CollabRelease)]
    assert [e.t for e in releases] == ref_releases == [pytest.approx(57.01, abs=0.05)]
    (done,) = [e for e in sim.events if e.kind == "subtask_done" and e.source == "agent/3"]
    assert done.data["satisfied"] and done.data["r"] == reference.states[3].outcomes[0].final_r
    assert [e.data["requester"] for e in sim.events if e.kind == "collab_follow"] == [3, -1]
    for j in (3, 4):
        ours = np.array([row[j] for row in trajectory])
        np.testing.assert_allclose(ours, reference.trajectory.states[j], rtol=0, atol=1e-12)


def test_the_quiet_tick_shortcut_of_events_drops_none(monkeypatch):
    """``StlCore._events`` returns () at once on a tick with no repair, recovery, message,
    change of follower or finished sub-task; on every tick of the stage-2 run (repairs, a
    request, following, a release, completions) that is what the full ``_all_events`` says."""
    checked = []
    events = stl_agent.StlCore._events

    def both(self, t, before, after, log, sent):
        got = events(self, t, before, after, log, sent)
        assert got == self._all_events(t, before, after, log, sent), t
        checked.append(len(got))
        return got

    monkeypatch.setattr(stl_agent.StlCore, "_events", both)
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loops = [stl_loop(network, FLEET, a)[0] for a in make_pair()]
    sim.control("start")
    drive(sim, loops, {3: np.array([0.0, -2.0, 0.0]), 4: np.array([0.0, 0.0, 0.0])},
          round(30.0 * RATE), round(28.0 * RATE))
    kinds = sim.kinds()
    assert {"repair", "collab_request", "collab_follow", "collab_release",
            "subtask_done"} <= set(kinds)
    assert len(checked) > 5000 and 5 < sum(n > 0 for n in checked) < 100
    # in the step a message comes with a repair or a finished sub-task; alone, it still counts
    core = stl_agent.StlCore(make_pair()[0])
    state = core.initial_state().agent
    quiet = LogRecord(1.0, 0.1, 0.5, 0.0, 0.0, 0, 0, 0, None, 0)
    assert core._events(1.0, state, state, quiet, ()) == ()
    (event,) = core._events(1.0, state, state, quiet, (CollabRelease(3, 4, 0),))
    assert event.kind == "collab_release" and event.data["receivers"] == [4]


def test_a_dead_partner_means_stage_3():
    """Robot 4's process dies (its liveliness token disappears) before robot 3's third critical
    event: robot 3 forgets 4's status, stage 2 is not enabled, the event gets stage 3 and no
    request is sent."""
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    (loop3, _), (loop4, transport4) = (stl_loop(network, FLEET, a) for a in make_pair())
    poses = {3: np.array([0.0, -2.0, 0.0]), 4: np.array([0.0, 0.0, 0.0])}
    sim.control("start")

    def kill_at_34(t, loops):
        if t == pytest.approx(34.0) and not loop4.stopped:
            transport4.kill()
            loop4.close()
            loop4.stopped = True

    drive(sim, [loop3, loop4], poses, 3000, 1500, before_tick=kill_at_34)
    repairs = [(e.t, e.data["stage"]) for e in sim.events
               if e.kind == "repair" and e.source == "agent/3"]
    assert [s for _, s in repairs[:3]] == [1, 1, 3]
    assert repairs[2][0] > 34.0
    assert "collab_request" not in sim.kinds()
    assert loop3.link.unreachable == frozenset({4})
    # robot 3 records the change once, at its first tick after the token went (34.0: the kill
    # came before that tick)
    (reach,) = [e for e in sim.events if e.kind == "peers_unreachable"]
    assert reach.source == "agent/3" and 34.0 <= reach.t < repairs[2][0]
    assert reach.data == {"peers": [4], "lost": [4], "back": []}


def test_an_unanswered_request_leaves_stage_2():
    """Robot 4 stays alive (token, frames) but stops answering queries after robot 3's last status
    announcement and before its request: the request fails, robot 3 leaves stage 2 (c_3 := 0)
    and its next critical event gets stage 3; robot 4 never follows."""
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    clock = FakeClock()
    (loop3, _), (loop4, _) = (stl_loop(network, FLEET, a, clock=clock) for a in make_pair())
    poses = {3: np.array([0.0, -2.0, 0.0]), 4: np.array([0.0, 0.0, 0.0])}
    sim.control("start")

    def deaf_at_34_5(t, loops):
        if t == pytest.approx(34.5):
            loop4.link.close()  # the queryable is gone, the liveliness token stays

    drive(sim, [loop3, loop4], poses, 3000, 1000, before_tick=deaf_at_34_5)
    repairs = [(e.t, e.data["stage"]) for e in sim.events
               if e.kind == "repair" and e.source == "agent/3"]
    assert [s for _, s in repairs[:4]] == [1, 1, 2, 3]
    assert [e.t for e in sim.events if e.kind == "collab_request"] == [repairs[2][0]]
    assert loop3.stats.collab_failures >= 1  # the request, then announcements not sent
    assert loop3.link.unreachable == frozenset({4})
    assert "collab_follow" not in sim.kinds()
    statuses = [s for s in sim.statuses if isinstance(s, StlStatus) and s.robot == 3]
    assert statuses[-1].c == 0
    reach = [(e.source, e.data) for e in sim.events if e.kind == "peers_unreachable"]
    assert reach == [("agent/3", {"peers": [4], "lost": [4], "back": []})]
    clock.advance(loop3.link.retry_after)  # a failed query is retried after a while
    assert loop3.link.unreachable == frozenset()
    drive(sim, [loop3, loop4], poses, 4001, 1)
    assert [e.data for e in sim.events if e.kind == "peers_unreachable"][-1] == \
        {"peers": [], "lost": [], "back": [4]}


def test_the_stl_process_main_on_the_fake_network():
    """``stl_agent.main`` end to end without sockets: alive once ready, answers a due frame,
    stops on Control(stop) with exit code 0 and an ``agent_stats`` event, token gone."""
    scenario = load_scenario("scenarios/scenario1.toml")
    network = FakeNetwork()
    sim = FakeSim(network, scenario.fleet)
    config = AgentConfig(robot=4, stale_after=0.5, collab_timeout=0.1)
    result = {}
    thread = threading.Thread(target=lambda: result.setdefault(
        "code", stl_agent.main(config, scenario, transport=network.transport("a4"),
                               stop=threading.Event())))
    thread.start()
    try:
        alive = keys.alive(scenario.fleet, "agent", 4)
        deadline = time.monotonic() + 10
        while alive not in network.alive_keys() and time.monotonic() < deadline:
            time.sleep(0.005)
        assert alive in network.alive_keys()
        sim.control("start")
        poses = {r.id: r.pose for r in scenario.robots}
        sim.frame(0.0, 0, poses, due=[4], offsets=[scenario.frame_offset(4)])  # mocap_at/3
        while not sim.commands and time.monotonic() < deadline:
            time.sleep(0.005)
        assert sim.commands[0].robot == 4 and len(sim.commands[0].u) == 3
        sim.control("stop")
        thread.join(10)
        assert not thread.is_alive() and result["code"] == 0
    finally:
        sim.control("stop")
        thread.join(10)
    (stats,) = [e for e in sim.events if e.kind == "agent_stats"]
    assert stats.source == "agent/4" and stats.data["steps"] == 1
    assert stats.data["collab_sent"] >= 1  # its status announcement to the absent peers
    assert alive not in network.alive_keys()


@pytest.mark.parametrize("lockstep", [True, False])
def test_messages_go_before_the_command_in_lockstep_and_after_it_in_realtime(lockstep):
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    (loop3, _), (loop4, _) = (stl_loop(network, FLEET, a) for a in make_pair())
    seen = []
    sim.transport.subscribe(keys.cmd(FLEET, 3), lambda _k, _p: seen.append(len(loop4.link.inbox)))
    sim.control("start")
    poses = {3: (0.0, -2.0, 0.0), 4: (0.0, 0.0, 0.0)}
    sim.frame(30.0, 3000, poses, due=[3, 4] if lockstep else [])
    loop3.run_once(0.0)  # its first step announces its status to robot 4
    assert seen == [1 if lockstep else 0]
    assert len(loop4.link.inbox) == 1


def test_status_readers_of_scenario_1():
    """build_agents announces only to the robots that read the announcements."""
    agents = build_agents(load_scenario("scenarios/scenario1.toml"))
    assert {i: a.cfg.peers for i, a in agents.items()} == {3: (4,), 4: (3,), 5: (4,)}
    assert {i: status_readers(i, a.cfg.library) for i, a in agents.items()} == {
        3: (4,), 4: (3,), 5: (4,)}


def readers_only(agent: StlAgent) -> StlAgent:
    return StlAgent(replace(agent.cfg, peers=status_readers(agent.robot_id, agent.cfg.library)))


def test_announcing_only_to_readers_changes_no_command():
    """§11.7 again: robot 4 reads no announcement (its task is its own), so robot 3 stops
    sending them to it; repairs, the stage-2 request, the follow and the trajectory stay the
    same, with fewer messages."""
    runs = {}
    for only_readers in (False, True):
        network = FakeNetwork()
        sim = FakeSim(network, FLEET)
        agents = make_pair()
        if only_readers:
            agents = tuple(readers_only(a) for a in agents)
        loops = [stl_loop(network, FLEET, a)[0] for a in agents]
        poses = {3: np.array([0.0, -2.0, 0.0]), 4: np.array([0.0, 0.0, 0.0])}
        sim.control("start")
        trajectory = drive(sim, loops, poses, 3000, 2800)
        runs[only_readers] = (trajectory, [(e.t, e.source, e.kind) for e in sim.events],
                              loops[0].link.sent)
    assert make_pair()[0].cfg.peers == (4,)
    assert readers_only(make_pair()[0]).cfg.peers == ()
    (traj_all, events_all, sent_all), (traj_readers, events_readers, sent_readers) = (
        runs[False], runs[True])
    assert ("collab_request" in {k for _, _, k in events_all}
            and "collab_follow" in {k for _, _, k in events_all})
    assert events_readers == events_all
    for j in (3, 4):
        np.testing.assert_array_equal([row[j] for row in traj_readers],
                                      [row[j] for row in traj_all])
    assert sent_readers < sent_all
