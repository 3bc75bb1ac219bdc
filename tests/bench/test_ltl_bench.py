"""The LTL benchmark script runs and writes valid JSON (no timing assertions: style.md §12)."""

from __future__ import annotations

import json
import subprocess
import sys


def test_quick_benchmark_writes_json(repo_root, tmp_path):
    output = tmp_path / "ltl_bench.json"
    done = subprocess.run(
        [sys.executable, str(repo_root / "bench" / "ltl_bench.py"), "--quick", "--output",
         str(output)],
        capture_output=True, text=True, timeout=120, check=False, cwd=repo_root,
    )
    assert done.returncode == 0, done.stderr
    assert "scaling grid" in done.stdout
    data = json.loads(output.read_text())
    assert data["quick"] is True
    assert {row["n"] for row in data["families"]} == {1, 2, 3}
    assert len(data["scenario_plans"]) == 5
    assert {row["regions"] for row in data["grid"]} == {10}
    for row in data["grid"] + data["scenario_plans"]:
        assert row["plan_ms"] > 0 and row["buchi_states"] >= 2
    # Algorithm 1 with the agent's kept automaton, and with the translation (step 1) included.
    assert {"algorithm1_ms", "algorithm1_full_ms"} <= set(data["results"])
    assert all(row["full_cpu_ms"] > 0 for row in data["agent_plans"])
