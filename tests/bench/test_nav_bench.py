"""The navigation benchmark runs in quick mode and writes the JSON it promises (no timings)."""

from __future__ import annotations

import json
import subprocess
import sys


def test_quick_benchmark_writes_every_figure(repo_root, tmp_path):
    output = tmp_path / "nav_bench.json"
    completed = subprocess.run(
        [
            sys.executable,
            str(repo_root / "bench" / "nav_bench.py"),
            "--quick",
            "--output",
            str(output),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert completed.returncode == 0, completed.stderr
    assert "dwa_cycle_5_others" in completed.stdout
    data = json.loads(output.read_text())
    assert data["quick"] is True and data["runs"] >= 5
    results = data["results"]
    for name in (
        "dwa_cycle_5_others",
        "plan_corner_to_corner_empty_arena",
        "harness_6_robots_one_executor",
    ):
        assert results[name]["median_ms"] > 0
        assert results[name]["runs"] >= 5
    assert set(data["meets_targets"]) == set(data["targets_ms"])
    # Scenario 1's LTL agents as their processes step them: they drive, and re-plan after some
    # commands (not all: most steps only run the DWA).
    for suffix in ("", "_numpy"):  # the DWA kernel the agents run, and the numpy one beside it
        step = results[f"ltl_agent_step_scenario1{suffix}"]
        assert step["moved"] and step["steps"] == 3 * 2 * 100
        assert 0 < step["cpu_median_ms"] <= step["cpu_p90_ms"] <= step["cpu_p99_ms"]
        assert 0 < results[f"ltl_agent_deferred_replan_scenario1{suffix}"]["per_step"] < 0.5
    assert results["ltl_agent_step_scenario1_numpy"]["kernel"] == "numpy"
    assert results["dwa_cycle_5_others_numpy"]["kernel"] == "numpy"
    assert results["dwa_cycle_5_others_numpy"]["admissible"] == results["dwa_cycle_5_others"][
        "admissible"]
    # The corner-to-corner path on the empty arena is the straight diagonal (6.4·√2 m).
    assert abs(results["plan_corner_to_corner_empty_arena"]["length_m"] - 6.4 * 2**0.5) < 1e-6
