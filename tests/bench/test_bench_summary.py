"""``bench/summary.py`` (the last step of ``make bench``) reads every layout the benchmarks write,
names a file it cannot read instead of crashing or skipping it in silence (a security_bench.json
without ``figures`` once stopped ``make bench`` at its very end)."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys


def _summary(repo_root):
    spec = importlib.util.spec_from_file_location("bench_summary",
                                                  repo_root / "bench" / "summary.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


COMMON = {  # bench/common.py's report(): what stl, ltl, runtime, tick, fault, backfill write
    "benchmark": "stl_bench", "load_average_before": [1.5, 1.0, 0.5],
    "time_utc": "2026-12-03T06:47:12Z",
    "figures": [
        {"key": "step", "label": "STL control step", "value": 28.0, "unit": "µs",
         "target": 50.0, "better": "lower", "wall": 28.1, "note": "", "met": True},
        {"key": "fleet", "label": "largest fleet", "value": 20.0, "unit": "robots",
         "target": 30.0, "better": "higher", "wall": None, "note": "", "met": False},
        {"key": "p50", "label": "latency p50", "value": float("nan"), "unit": "ms",
         "target": None, "better": "lower", "wall": None, "note": "", "met": None}]}
NAV = {  # nav_bench's own layout
    "benchmark": "nav", "load_average_before": [2.0, 2.0, 2.0],
    "targets_ms": {"dwa": 2.0}, "meets_targets": {"dwa": True},
    "results": {"dwa": {"cpu_median_ms": 0.339, "median_ms": 0.34}}}
OUTCOMES = {"machine": "x86_64", "rows": []}  # scenario_bench, fleet_bench: no timed targets


def test_every_layout_gives_rows_and_a_broken_file_is_named(repo_root, tmp_path):
    for name, data in (("stl", COMMON), ("nav", NAV), ("scenario", OUTCOMES)):
        (tmp_path / f"{name}_bench.json").write_text(json.dumps(data))
    (tmp_path / "broken_bench.json").write_text('{"figures": [{"value": 1')
    table, problems = _summary(repo_root).rows(tmp_path)
    by_label = {label: (bench, value, wall, target, met)
                for bench, label, value, wall, target, met in table}
    assert by_label["STL control step"] == ("stl_bench", "28 µs", "28.1 µs", "≤ 50 µs",
                                            "met  (load 1.5, 06:47Z)")
    assert by_label["largest fleet"][3:] == ("≥ 30 robots", "NOT MET  (load 1.5, 06:47Z)")
    assert by_label["latency p50"][1:] == ("n/a", "-", "-", "")
    assert by_label["dwa"] == ("nav", "0.339 ms", "0.34 ms", "≤ 2 ms", "met  (load 2.0)")
    assert by_label["no timed figures here: see scenario_bench.json"][0] == "scenario_bench"
    assert len(problems) == 1 and "broken_bench.json" in problems[0]


def test_the_command_fails_on_a_broken_file_and_prints_the_rest(repo_root, tmp_path):
    (tmp_path / "stl_bench.json").write_text(json.dumps(COMMON))
    (tmp_path / "broken_bench.json").write_text("[1, 2]")
    done = subprocess.run([sys.executable, str(repo_root / "bench" / "summary.py"),
                           str(tmp_path)], capture_output=True, text=True, timeout=60,
                          check=False)
    assert done.returncode == 1
    assert "STL control step" in done.stdout
    assert "unreadable:" in done.stderr and "broken_bench.json" in done.stderr
