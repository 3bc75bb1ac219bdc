"""Smoke run of ``bench/stl_bench.py --quick``: it runs and writes well-formed JSON (no timing
assertions: benchmarks are programs, not timed tests)."""

from __future__ import annotations

import json
import subprocess
import sys


def test_bench_quick_writes_json(repo_root, tmp_path):
    out = tmp_path / "stl_bench.json"
    done = subprocess.run([sys.executable, str(repo_root / "bench" / "stl_bench.py"), "--quick",
                           "--out", str(out)], capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 0, done.stderr
    assert "control step" in done.stdout
    data = json.loads(out.read_text())
    assert data["quick"] is True and data["runs"] >= 5
    assert set(data["results"]) == {"step_us", "step_obstacles_us", "tick3_us", "monitor_ms",
                                    "harness_speed"}
    assert data["monitor_samples"] == 9001 and data["load_average_before"]
    assert all(f["met"] in (True, False, None) for f in data["figures"])
    assert all(value > 0 for value in data["results"].values())
