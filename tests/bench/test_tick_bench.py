"""``bench/tick_bench.py`` runs in quick mode and writes the figures it promises (no timings are
judged: the benchmark has no targets), including an STL agent's tick back to back and after a
10 ms sleep (docs/performance.md round 11), and one agent's whole loop tick of a
30-robot fleet (the loop itself raises if a frame went unanswered)."""

from __future__ import annotations

import json
import subprocess
import sys


def test_quick_tick_bench_writes_every_figure(repo_root, tmp_path):
    output = tmp_path / "tick_bench.json"
    completed = subprocess.run(
        [sys.executable, str(repo_root / "bench" / "tick_bench.py"), "--quick", "--runs", "3",
         "--out", str(output)],
        capture_output=True, text=True, timeout=300, check=False)
    assert completed.returncode == 0, completed.stderr
    figures = {f["key"]: f for f in json.loads(output.read_text())["figures"]}
    assert {"decode_frame_us", "world_tick_us", "stl_agent_tick_us",
            "stl_agent_tick_after_sleep_us", "stl_loop_tick_us",
            "stl_loop_tick_after_sleep_us"} <= set(figures)
    assert all(f["value"] > 0 for f in figures.values())
    assert "× the tick back to back" in figures["stl_agent_tick_after_sleep_us"]["note"]
    assert "× the tick back to back" in figures["stl_loop_tick_after_sleep_us"]["note"]
    assert "30-robot fleet" in figures["stl_loop_tick_us"]["label"]
    assert "after a 10 ms sleep" in completed.stdout
    from tlfleet.bus.protocol.fast_paths import native_codec

    if native_codec():  # both codecs, each figure under its own key
        assert {"decode_frame_python_us", "encode_command_python_us",
                "stl_agent_tick_after_sleep_python_us"} <= set(figures)
        assert figures["decode_frame_us"]["note"] == "C codec"
        assert figures["decode_frame_python_us"]["note"] == "Python codec"
