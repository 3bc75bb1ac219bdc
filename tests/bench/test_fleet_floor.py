"""``bench/fleet_floor.py``, the fleet size's floor: N agent-like processes answering a
sim-like process's spread frames over zenoh on loopback. Checked: every receiver starts, answers
and reports its CPU; the deadlines are counted per (receiver, period) as the simulator counts
them, so receivers whose work outlasts the period miss most of them and quick ones few."""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from tlfleet.agent.scenario import load_scenario  # noqa: E402
from tlfleet.coordinator.run import RunConfig, child_sched  # noqa: E402

from bench.fleet_floor import SLOTS, fleet_probe, slot_of  # noqa: E402
from bench.floor_probe import realtime_sched  # noqa: E402
from bench.runtime_bench import generated_fleet  # noqa: E402


def _port(offset: int) -> int:
    return 41000 + 7 * (os.getpid() % 3000) + offset


@pytest.mark.parametrize("n", [5, 7, 20, 30, 31])
def test_the_floors_receivers_share_slots_as_the_fleets_robots_share_frame_instants(n, tmp_path):
    """Receivers on one slot are exactly the generated fleet's robots on one frame instant
    (``Scenario.frame_offset`` with ``[sim] frame_slots`` = the floor's slots), in the same
    order of instants."""
    path = tmp_path / "fleet.toml"
    path.write_text(generated_fleet(n, 10.0))
    scenario = load_scenario(path)
    assert scenario.sim.frame_slots == SLOTS  # the default the floor follows
    offsets = [scenario.frame_offset(i + 1) for i in range(n)]
    slots = [slot_of(i, n, SLOTS) for i in range(n)]
    assert len(set(slots)) == min(n, SLOTS)
    for i in range(n):
        for j in range(n):
            assert (slots[i] == slots[j]) == (offsets[i] == offsets[j]), (i, j)
            assert (slots[i] < slots[j]) == (offsets[i] < offsets[j]), (i, j)


def test_quick_receivers_answer_every_period_of_their_slot():
    row = fleet_probe(n=3, slots=2, work_us=30.0, sender_work_us=10.0, seconds=0.5,
                      port=_port(0))
    assert row["receivers_reported"] == 3
    assert row["periods"] == 50 and row["due"] == 150
    assert 0 <= row["missed"] <= row["due"]
    assert row["missed_fraction"] < 0.5  # 30 µs of work in a 10 ms period: answered in time
    assert 0.0 < row["latency_p50_ms"] <= row["latency_p99_ms"]
    assert math.isfinite(row["rx_cpu_us"]) and row["rx_cpu_us"] > 30.0  # the work, at least
    assert 0.0 <= row["idle_pct"] <= 100.0 and row["sender_cpu_pct"] > 0.0


def test_receivers_slower_than_the_period_miss_most_deadlines():
    """20 ms of work per frame: a receiver answers at most every other period, each answer more
    than one period after its frame, so at least half the deadlines are missed. (As ordinary
    processes: two real-time ones spinning 20 ms a period would hold both cores.)"""
    row = fleet_probe(n=2, slots=1, work_us=20_000.0, sender_work_us=10.0, seconds=0.5,
                      port=_port(1), sched="default")
    assert row["receivers_reported"] == 2
    assert row["missed_fraction"] >= 0.5
    assert row["latency_p50_ms"] > 10.0


@pytest.mark.skipif(not hasattr(os, "SCHED_BATCH"), reason="Linux scheduling policies")
def test_the_fleet_floor_is_scheduled_as_the_realtime_fleet():
    """By default its processes take the policy a realtime ``tlfleet run`` gives the fleet's
    (fifo where permitted, else the OS default: round 17); asked for batch, they run under it."""
    assert realtime_sched() == child_sched(RunConfig(ROOT / "x.toml", mode="realtime"))
    row = fleet_probe(n=1, slots=1, work_us=10.0, sender_work_us=10.0, seconds=0.2,
                      port=_port(2), sched="batch")
    assert row["sched"] == "batch" and row["policy"] == os.SCHED_BATCH, row
    assert fleet_probe(n=1, slots=1, work_us=10.0, sender_work_us=10.0, seconds=0.2,
                       port=_port(3))["sched"] == realtime_sched()
