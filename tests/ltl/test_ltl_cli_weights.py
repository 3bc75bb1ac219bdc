"""`tlfleet plan --weights`: map distances go around obstacles, Euclidean ones do not."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tlfleet.cli.main import main

WALLED = """
name = "walled"
duration = 60.0
[[arena.obstacles]]
shape = "rect"
xmin = -0.1
xmax = 0.1
ymin = -3.5
ymax = 2.5
[[regions]]
name = "a1"
center = [-2.0, -2.0]
[[regions]]
name = "a2"
center = [2.0, -2.0]
[[robots]]
id = 1
kind = "unicycle"
pose = [-2.0, -2.0, 0.0]
ltl = "G F a1 & G F a2"
"""


def plan_json(path: Path, weights: str, capsys) -> dict:
    assert main(["plan", str(path), "--json", "--weights", weights]) == 0
    return json.loads(capsys.readouterr().out)["plans"][0]


def test_map_weights_go_around_the_wall(tmp_path: Path, capsys):
    path = tmp_path / "walled.toml"
    path.write_text(WALLED)
    euclid = plan_json(path, "euclidean", capsys)
    mapped = plan_json(path, "map", capsys)
    assert euclid["suffix_cost"] == 8.0  # a1 ↔ a2 straight through the wall, both ways
    assert mapped["suffix_cost"] > 2 * (2 * 4.5 + 0.1)  # around the wall's free end at y = 2.5
    assert mapped["prefix"] == euclid["prefix"]


def test_piping_into_a_closed_reader_is_not_an_error(repo_root: Path):
    """`tlfleet plan ... | head -1`: the reader has gone before we write; exit quietly with 0."""
    proc = subprocess.Popen([sys.executable, "-m", "tlfleet.cli", "plan",
                             "scenarios/scenario1.toml"], cwd=repo_root,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # closed before the child has even imported: its first write fails
    stderr = proc.stderr.read().decode()
    proc.stderr.close()
    assert proc.wait(timeout=60) == 0
    assert "Traceback" not in stderr and "BrokenPipe" not in stderr
