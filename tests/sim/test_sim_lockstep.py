"""The tick logic without sockets: due robots, lockstep collection, realtime latest-wins,
tick ↔ time conversion and wall-clock pacing (architecture.md §3)."""

from __future__ import annotations

from dataclasses import replace

import pytest
from sim_helpers import omni, scenario, unicycle
from tlfleet.bus.protocol.messages import Command
from tlfleet.sim.clock import Pacer, TickClock
from tlfleet.sim.lockstep import (
    LatestCommands,
    LockstepCollector,
    Offer,
    control_dividers,
    control_phases,
    due_robots,
)
from tlfleet.sim.stats import TimingStats


def cmd(robot: int, seq: int, u=(0.0, 0.0, 0.0)) -> Command:
    return Command(robot, seq / 100, seq, u)


def test_control_dividers_follow_each_robots_task_kind():
    scen = scenario(unicycle(1, 0, 0), omni(2, 1, 0), unicycle(3, 2, 0), omni(4, 0, 1))
    assert control_dividers(scen) == {1: 20, 2: 1, 3: 20, 4: 1}  # LTL 5 Hz, STL 100 Hz
    slow = scenario(unicycle(1, 0, 0), omni(2, 1, 0), stl_rate=30.0, ltl_rate=1000.0)
    assert control_dividers(slow) == {1: 1, 2: 3}  # round(100/30) = 3; never below 1


@pytest.mark.parametrize(("tick", "alive", "expected"), [
    (0, {1, 2, 3}, (1, 2, 3)),
    (1, {1, 2, 3}, (2,)),
    (20, {1, 2, 3}, (1, 2, 3)),
    (40, {2, 3}, (2, 3)),
    (40, {1, 9}, (1,)),  # 9 is not a robot of the scenario
    (7, set(), ()),
])
def test_due_robots(tick, alive, expected):
    assert due_robots(tick, {3: 20, 1: 20, 2: 1}, alive, {}) == expected


def test_ltl_robots_are_staggered_over_their_control_period():
    """N LTL robots at divider d are due at phases ⌊rank·d/n⌋ (id order), so no two
    step on the same tick; STL robots and ``stagger = false`` keep phase 0."""
    scen = scenario(unicycle(3, 0, 0), omni(2, 1, 0), unicycle(1, 2, 0), omni(4, 0, 1))
    phases = control_phases(scen)
    assert phases == {1: 0, 2: 0, 3: 10, 4: 0}
    dividers = control_dividers(scen)
    alive = {1, 2, 3, 4}
    due = {k: due_robots(k, dividers, alive, phases) for k in range(60)}
    assert [k for k in due if 1 in due[k]] == [0, 20, 40]
    assert [k for k in due if 3 in due[k]] == [10, 30, 50]
    assert all({2, 4} <= set(d) for d in due.values())
    three = scenario(*(unicycle(i, i, 0) for i in (5, 6, 7)))
    assert control_phases(three) == {5: 0, 6: 6, 7: 13}
    aligned = replace(scen, ltl=replace(scen.ltl, stagger=False))
    assert control_phases(aligned) == {1: 0, 2: 0, 3: 0, 4: 0}
    assert due_robots(0, dividers, alive, control_phases(aligned)) == (1, 2, 3, 4)


def test_lockstep_collector_accepts_one_command_per_due_robot_of_the_open_seq():
    c = LockstepCollector(robots=(1, 2, 3))
    assert c.offer(cmd(1, 3)) is Offer.BEFORE_START
    c.begin(5, due=(2, 1))
    assert c.due == (1, 2) and not c.complete and c.missing() == (1, 2)
    assert c.offer(cmd(2, 4)) is Offer.WRONG_SEQ  # late for tick 4
    assert c.offer(cmd(2, 6)) is Offer.WRONG_SEQ  # from the future
    assert c.offer(cmd(3, 5)) is Offer.NOT_DUE
    assert c.offer(cmd(7, 5)) is Offer.UNKNOWN_ROBOT
    assert c.offer(cmd(2, 5, (0.1, 0.0, 0.0))) is Offer.ACCEPTED
    assert c.offer(cmd(2, 5, (0.2, 0.0, 0.0))) is Offer.DUPLICATE
    assert c.missing() == (1,)
    assert c.offer(cmd(1, 5)) is Offer.ACCEPTED
    assert c.complete
    assert [x.robot for x in c.take()] == [1, 2]  # ascending, whatever the arrival order
    assert c.counts == {Offer.BEFORE_START: 1, Offer.WRONG_SEQ: 2, Offer.NOT_DUE: 1,
                        Offer.UNKNOWN_ROBOT: 1, Offer.ACCEPTED: 2, Offer.DUPLICATE: 1}
    assert c.take() == []


def test_early_answers_to_the_initial_frame_are_held_for_tick_0():
    c = LockstepCollector(robots=(1, 2, 3))
    assert c.offer(cmd(1, 0, (0.1, 0.0, 0.0))) is Offer.EARLY
    assert c.offer(cmd(1, 0, (0.5, 0.0, 0.0))) is Offer.BEFORE_START  # one early answer each
    assert c.offer(cmd(3, 0)) is Offer.EARLY
    assert c.offer(cmd(2, 1)) is Offer.BEFORE_START
    assert c.begin(0, due=(1, 2)) == (1,)  # robot 3 is not due (its agent is not alive)
    assert c.missing() == (2,)
    assert c.offer(cmd(1, 0, (0.9, 0.0, 0.0))) is Offer.DUPLICATE
    c.offer(cmd(2, 0))
    assert [(x.robot, x.u[0]) for x in c.take()] == [(1, 0.1), (2, 0.0)]
    assert c.begin(1, due=(1,)) == ()


def test_first_command_of_a_tick_wins_over_duplicates():
    c = LockstepCollector(robots=(1,))
    c.begin(0, due=(1,))
    c.offer(cmd(1, 0, (0.1, 0.0, 0.0)))
    c.offer(cmd(1, 0, (0.9, 0.0, 0.0)))
    assert c.take()[0].u == (0.1, 0.0, 0.0)


def test_dead_agent_is_dropped_and_timeout_records_misses():
    c = LockstepCollector(robots=(1, 2, 3))
    c.begin(0, due=(1, 2, 3))
    c.offer(cmd(2, 0))
    c.drop(3)
    assert c.missing() == (1,)
    assert c.offer(cmd(3, 0)) is Offer.NOT_DUE  # dropped: a late word from it is ignored
    assert c.expire() == (1,)
    assert c.complete
    assert c.misses == {1: 1}
    assert [x.robot for x in c.take()] == [2]
    c.begin(1, due=(1,))
    assert c.expire() == (1,)
    assert c.misses == {1: 2}


def test_empty_tick_is_complete_at_once():
    c = LockstepCollector(robots=(1,))
    c.begin(3, due=())
    assert c.complete and c.expire() == () and c.take() == []


def test_realtime_latest_command_wins_and_is_taken_once():
    latest = LatestCommands(robots=(1, 2))
    assert latest.offer(cmd(1, 2)) is Offer.BEFORE_START
    assert latest.offer(cmd(1, 0)) is Offer.EARLY  # held for tick 0, unless overtaken
    latest.started = True
    latest.offer(cmd(2, 3, (0.1, 0.0, 0.0)))
    latest.offer(cmd(1, 3))
    latest.offer(cmd(2, 4, (0.2, 0.0, 0.0)))
    assert latest.offer(cmd(5, 4)) is Offer.UNKNOWN_ROBOT
    taken = latest.take()
    assert [(x.robot, x.seq) for x in taken] == [(1, 3), (2, 4)]
    assert latest.take() == []


@pytest.mark.parametrize(("rate", "tick", "t"), [(100.0, 0, 0.0), (100.0, 1, 0.01),
                                                   (100.0, 9000, 90.0), (30.0, 7, 7 / 30)])
def test_tick_time_is_computed_not_accumulated(rate, tick, t):
    assert TickClock(rate).time(tick) == t


@pytest.mark.parametrize(("duration", "last"), [(90.0, 9000), (0.0, 0), (0.015, 2), (1.0, 100)])
def test_last_tick_reaches_the_duration(duration, last):
    clock = TickClock(100.0)
    assert clock.last_tick(duration) == last
    assert clock.time(last) >= duration - 1e-9


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_pacer_keeps_the_period_and_restarts_after_an_overrun():
    clock = FakeClock()
    pacer = Pacer(0.01, clock)
    assert pacer.remaining() == pytest.approx(0.01)
    clock.now += 0.004
    assert pacer.remaining() == pytest.approx(0.006)
    clock.now += 0.006
    assert pacer.remaining() <= 1e-12
    pacer.advance()  # the next tick is due one period after the previous due time
    assert pacer.next_due == pytest.approx(100.02)
    clock.now = 100.025  # a bit late: catch up, no overrun
    pacer.advance()
    assert pacer.next_due == pytest.approx(100.03) and pacer.overruns == 0
    clock.now = 100.2  # far behind: restart from now instead of bursting
    pacer.advance()
    assert pacer.overruns == 1
    assert pacer.next_due == pytest.approx(100.21)


def test_timing_stats_latency_and_missed_deadlines():
    stats = TimingStats(keep_frames=2)
    stats.frame_published(0, 10.000)
    stats.frame_published(1, 10.010)
    stats.command_arrived(1, 0, 10.002)
    stats.command_arrived(2, 1, 10.013)
    assert stats.close_tick(1, due=(1, 2)) == (1,)  # robot 1 answered tick 0 only
    stats.frame_published(2, 10.020)  # forgets tick 0
    stats.command_arrived(1, 0, 10.030)  # a very late answer: no latency without its frame
    assert stats.close_tick(2, due=iter([2])) == (2,)
    summary = stats.summary()
    assert (summary["commands"], summary["due"], summary["missed"]) == (2, 3, 2)
    assert summary["latency_max_ms"] == pytest.approx(3.0)
    assert summary["latency_p50_ms"] == pytest.approx(2.5)
    assert summary["latency_p99_ms_by_robot"] == {"1": pytest.approx(2.0),
                                                  "2": pytest.approx(3.0)}
    assert "latency_p50_ms" not in TimingStats().summary()


def test_timing_stats_split_the_every_tick_robots_by_shared_ticks():
    """The every-tick robots' latencies on the ticks an LTL robot is due too
    (``shared``) and on the others."""
    stats = TimingStats(every_tick=[3], shared=lambda seq: seq % 20 == 10)
    plain = TimingStats()
    for seq in range(40):
        for timing in (stats, plain):
            timing.frame_published(seq, seq * 0.01)
            timing.command_arrived(3, seq, seq * 0.01 + (0.004 if seq % 20 == 10 else 0.001))
            if seq % 20 == 10:
                timing.command_arrived(1, seq, seq * 0.01 + 0.006)  # the LTL robot: not split
    summary = stats.summary()
    assert summary["latency_p50_ms_shared"] == pytest.approx(4.0)
    assert summary["latency_p99_ms_shared"] == pytest.approx(4.0)
    assert summary["latency_p99_ms_alone"] == pytest.approx(1.0)
    assert "latency_p50_ms_shared" not in plain.summary()
