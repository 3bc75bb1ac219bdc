"""bench/recorder_lag_bench.py's lag: the probe's sim time minus what the coordinator had
recorded at its last step before the probe's sample, checked on hand-made series."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from recorder_lag_bench import lag_series


def test_lag_series() -> None:
    coordinator = [(10.0, 0.0), (10.5, 1.0), (12.0, 1.2)]  # stalled from 10.5 to 12.0 s wall
    probe = [(9.9, 0.0), (10.0, 0.01), (10.6, 1.1), (11.9, 6.0), (12.0, 6.1), (12.1, 6.2)]
    assert lag_series(probe, coordinator) == pytest.approx([0.01, 0.1, 5.0, 4.9, 5.0])


def test_no_coordinator_step_no_lag() -> None:
    assert lag_series([(1.0, 0.5)], []) == []
