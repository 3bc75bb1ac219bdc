"""``tlfleet ros-mirror`` beside a simulated realtime run, seen by a real rclpy subscriber in an
isolated namespace: what it publishes is the run the coordinator recorded."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from ros_harness import need_ros, run_case, unique_domain

ROOT = Path(__file__).resolve().parents[2]
pytestmark = [pytest.mark.system, pytest.mark.needs_system, pytest.mark.ros]


def test_the_mirror_publishes_the_recorded_run(tmp_path):
    need_ros()
    scenario = ROOT / "tests" / "system" / "two_robots.toml"
    result = run_case({"kind": "mirror", "scenario": str(scenario), "domain_id": unique_domain(),
                       "duration": 6.0}, tmp_path, timeout=180)
    assert result["run_rc"] == 0 and result["mirror_rc"] == 0, result["mirror_log"]
    got = result["got"]
    with open(Path(result["run_dir"]) / "trajectory.csv", newline="") as handle:
        rows = np.array(list(csv.reader(handle))[1:], dtype=float)
    by_t = {round(row[0], 6): row for row in rows}
    poses = got["pose1"]
    assert len(poses) > 50  # ≈ 50 Hz over the run's last seconds
    for t, x, y, th, frame in poses:
        row = by_t[round(t, 6)]  # a frame the recorder recorded, at the same sim time
        assert (x, y) == pytest.approx((row[1], row[2]), abs=1e-12) and frame == "world"
        assert math.cos(th - row[3]) == pytest.approx(1.0, abs=1e-12)
    arrays = got["array"]
    t, xy = arrays[-1]
    row = by_t[round(t, 6)]
    assert np.allclose(xy, [[row[1], row[2]], [row[4], row[5]]], atol=1e-12, rtol=0)
    odom = got["odom2"]
    assert {o[4] for o in odom} == {"robot2"}
    assert max(math.hypot(o[2], o[3]) for o in odom) > 0.05  # robot 2 moves
    assert max(math.hypot(o[2], o[3]) for o in odom) < 0.35  # within its limits (+ one frame)
    scene = got["scene"][0]
    assert [m[1] for m in scene if m[0] == "region_names"] == ["a1", "a2"]
    diag = [s for array in got["diag"] for s in array]
    assert {s[0] for s in diag if s[0].startswith("robot")} == {"robot1", "robot2"}
    assert any(s[0] == "robot2" and "rho" in s[3] for s in diag)
    assert any(s[1] == "sim_done" and s[0] == "sim" for s in diag)
