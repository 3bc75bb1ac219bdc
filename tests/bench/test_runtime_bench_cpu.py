"""``bench/runtime_bench.py``'s CPU per simulated second: from the mission's
start (interpolated between samples) to each child's last sample, the coordinator to the last
progress call, over the mission's sim time; independent of when the coordinator saw frames."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from bench.runtime_bench import CpuSampler  # noqa: E402


def test_cpu_per_sim_s_spans_the_mission_of_every_process():
    sampler = CpuSampler()
    # (monotonic s, cumulated CPU s): start-up CPU before the mission start at t = 10
    sampler.samples = {
        1: ("sim", [(9.5, 2.0), (10.5, 2.5), (11.5, 3.5), (12.0, 3.9)]),       # exits at 12
        2: ("agent-3", [(9.5, 1.0), (10.5, 1.2), (12.0, 1.8)]),
        3: ("agent-4", [(10.8, 0.5), (12.0, 0.9)]),                            # seen after start
        4: ("coordinator", [(9.5, 4.0), (11.0, 4.3), (12.0, 4.5), (15.0, 9.0)]),  # then a report
        5: ("router", [(9.0, 0.1)]),                                           # one sample: none
    }
    got = sampler.cpu_per_sim_s(start=10.0, end=12.0, t_end=90.0)
    assert got["sim"] == pytest.approx((3.9 - 2.25) / 90.0)  # 2.25: halfway from 2.0 to 2.5
    assert got["agent-3"] == pytest.approx((1.8 - 1.1) / 90.0)
    assert got["agent-4"] == pytest.approx((0.9 - 0.5) / 90.0)
    assert got["agents"] == pytest.approx(got["agent-3"] + got["agent-4"])
    assert got["coordinator"] == pytest.approx((4.5 - 4.1) / 90.0)  # not the report's CPU
    assert "router" not in got
    assert sampler.cpu_per_sim_s(start=10.0, end=12.0, t_end=0.0) == {}
