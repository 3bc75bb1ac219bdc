"""``bench/floor_probe.py``'s lockstep floor: the lockstep fleet's shape with fixed work
per process, over bare UDP and over zenoh. Checked: every run completes on loopback, the sender
really waits for every agent's answer before the next frame (a frame cannot go faster than one
agent's work), and the speed-up is the frame rate over the 100 Hz mocap rate."""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from tlfleet.coordinator.run import RunConfig, child_sched  # noqa: E402

from bench.floor_probe import lockstep_probe, lockstep_sched  # noqa: E402


@pytest.mark.parametrize("transport", ["udp", "zenoh"])
def test_lockstep_floor_runs_and_waits_for_every_agent(transport):
    work_us = 2000.0  # each agent busy 2 ms per frame: at most 500 frames per wall second
    result = lockstep_probe(runs=1, seconds=0.2, agents=2, work_us=work_us, sim_work_us=10.0,
                            transports=(transport,))
    row = result[transport]
    assert [r.get("error") for r in row["runs"]] == [None]
    assert math.isfinite(row["frames_per_s"]) and row["frames_per_s"] > 0.0
    assert row["frames_per_s"] <= 1e6 / work_us  # the lockstep wait, not a timing target
    assert row["speedup"] == pytest.approx(row["frames_per_s"] / 100.0)
    assert row["sender_cpu_us"] > 0.0
    assert (row["agents"], row["work_us"], row["sim_work_us"]) == (2, work_us, 10.0)


@pytest.mark.skipif(not hasattr(os, "SCHED_BATCH"), reason="Linux scheduling policies")
def test_the_lockstep_floor_is_scheduled_as_the_fleet():
    """By default its processes take the policy a lockstep ``tlfleet run`` gives the fleet's
    (fifo where permitted, else batch: round 16); asked for batch, the sender runs under it."""
    assert lockstep_sched() == child_sched(RunConfig(ROOT / "x.toml", mode="lockstep"))
    result = lockstep_probe(runs=1, seconds=0.1, agents=1, work_us=10.0, sim_work_us=10.0,
                            transports=("udp",), sched="batch")
    row = result["udp"]
    assert row["sched"] == "batch"
    assert [r.get("policy") for r in row["runs"]] == [os.SCHED_BATCH], row["runs"]


@pytest.mark.parametrize("transport", ["udp", "zenoh"])
def test_lockstep_floor_waits_for_the_decimated_agents_on_their_ticks(transport):
    ltl_work_us, divider = 5000.0, 4  # one 5 ms answer every 4 frames: ≤ 800 frames a second
    result = lockstep_probe(runs=1, seconds=0.2, agents=1, work_us=10.0, sim_work_us=10.0,
                            transports=(transport,), ltl_agents=1, ltl_work_us=ltl_work_us,
                            divider=divider)
    row = result[transport]
    assert [r.get("error") for r in row["runs"]] == [None]
    assert 0.0 < row["frames_per_s"] <= divider * 1e6 / ltl_work_us
    assert (row["ltl_agents"], row["ltl_work_us"], row["divider"]) == (1, ltl_work_us, divider)


def test_the_decimated_agents_are_staggered_as_the_fleets_ltl_agents():
    from bench.floor_probe import ltl_phases

    assert ltl_phases(2, 20) == [0, 10]
    assert ltl_phases(3, 20) == [0, 6, 13]
    assert ltl_phases(0, 20) == []


def test_the_inline_echo_answers_every_frame_from_zenohs_thread():
    """Round 13's ``zenoh-inline`` variant: the work and the answer run inside zenoh's callback
    (no Python thread woken); every frame is answered and its CPU per tick is measured."""
    from bench.floor_probe import run_pair

    port = 40000 + 3 * (os.getpid() % 5000)  # sender, receiver (the relay port unused)
    row = run_pair("zenoh-inline", port, 0.5, 30.0)
    assert row.get("error") is None
    assert row["ticks"] == 50 and row["answered"] == 50
    assert math.isfinite(row["rx_cpu_us"]) and row["rx_cpu_us"] >= 30.0  # the busy work alone


@pytest.mark.skipif(not hasattr(os, "SCHED_BATCH"), reason="Linux scheduling policies")
def test_the_echo_probe_is_scheduled_as_the_realtime_fleet():
    """By default its processes take the policy a realtime ``tlfleet run`` gives the fleet's
    (fifo where permitted, else the OS default: round 17), so the latency floor and the fleet's
    latency are measured alike; asked for batch, the receiver runs under it."""
    from bench.floor_probe import probe, realtime_sched

    assert realtime_sched() == child_sched(RunConfig(ROOT / "x.toml", mode="realtime"))
    base = 40500 + 9 * (os.getpid() % 2000)
    row = probe(runs=1, seconds=0.2, variants=("udp",), base_port=base, sched="batch")["udp"]
    assert row["sched"] == "batch"
    assert [r.get("policy") for r in row["runs"]] == [os.SCHED_BATCH], row["runs"]
    assert probe(runs=1, seconds=0.2, variants=("udp",),
                 base_port=base + 9)["udp"]["sched"] == realtime_sched()


def test_a_busy_port_moves_the_echo_probe_on_and_never_ends_the_benchmark(monkeypatch):
    """The probe's ports overlap the ephemeral range, where the OS may have given one to a
    fleet's connection: the next ports are tried, and after them an error row, not a raise."""
    import bench.floor_probe as fp

    tried = []

    def run_pair(variant, port, seconds, work_us, sched="default"):
        tried.append(port)
        if port < 30006:
            raise RuntimeError(f"floor probe receiver ({variant}) did not start")
        return {"rx_cpu_us": 1.0, "ticks": 1, "answered": 1, "rtt_p50_us": 1.0, "rtt_p99_us": 1.0}

    monkeypatch.setattr(fp, "run_pair", run_pair)
    assert fp._pair_on_a_free_port("udp", 30000, 0.1, 30.0)["answered"] == 1
    assert tried == [30000, 30003, 30006]
    tried.clear()
    row = fp._pair_on_a_free_port("udp", 20000, 0.1, 30.0)
    assert tried == [20000, 20003, 20006]
    assert math.isnan(row["rx_cpu_us"]) and "did not start on 3 ports from 20000" in row["error"]
