"""`tlfleet plan`, `check` and `run` agree on the keep-out rule (docs/ltl-navigation.md §2): a task
whose only way passes through a region it must keep out of is refused by all three, before
anything starts, in one line that names the region in the way."""

from __future__ import annotations

from pathlib import Path

import pytest
from tlfleet.cli.main import main

GAP = """
name = "gap"
duration = 30.0
[[arena.obstacles]]
shape = "rect"
xmin = -0.1
xmax = 0.1
ymin = -3.5
ymax = -0.6
[[arena.obstacles]]
shape = "rect"
xmin = -0.1
xmax = 0.1
ymin = 0.6
ymax = 3.5
[[regions]]
name = "a"
center = [-2.0, 0.0]
[[regions]]
name = "b"
center = [2.0, 0.0]
[[regions]]
name = "spill"
center = [0.0, 0.0]
radius = 0.3
[[robots]]
id = 1
kind = "unicycle"
pose = [-2.0, -1.0, 0.0]
ltl = "G F a & G F b & G !spill"
"""


@pytest.mark.parametrize("command", [["plan"], ["check"], ["run", "--no-report", "--quiet"]])
def test_no_plan_through_a_keep_out_zone_is_one_line_naming_it(tmp_path: Path, capsys,
                                                                command):
    path = tmp_path / "gap.toml"
    path.write_text(GAP)
    out = tmp_path / "run"
    argv = [command[0], str(path), *command[1:]] + (["--out", str(out)] if command[0] == "run"
                                                     else [])
    assert main(argv) == 1
    err = [line for line in capsys.readouterr().err.strip().splitlines()
           if "links are plain TCP" not in line]  # run's notice about its links comes first
    assert len(err) == 1, err
    # plan names the robot; check and run name the file and the field first (check_launch)
    head = "" if command[0] == "plan" else f"{path}: robots[id=1].ltl: robot 1's agent cannot " \
        "start: "
    assert err[0].startswith(f"tlfleet {command[0]}: {head}robot 1: task "), err[0]
    assert "every way from a to b enters region 'spill'" in err[0]
    assert not out.exists()  # nothing started, no run directory


def test_without_the_forbidden_region_in_the_gap_all_three_plan(tmp_path: Path, capsys):
    path = tmp_path / "gap.toml"
    path.write_text(GAP.replace("center = [0.0, 0.0]\nradius = 0.3",
                               "center = [0.0, 2.5]\nradius = 0.3"))
    assert main(["plan", str(path)]) == 0
    assert "suffix: (b -> a -> b)^ω" in capsys.readouterr().out
    assert main(["check", str(path)]) == 0
