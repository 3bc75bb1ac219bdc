"""The figures for papers: PNG, PDF and SVG; STL goals taken from the tasks; one colour map a
robot; mathtext labels."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_report import write_synthetic
from tlfleet.agent.scenario import load_scenario
from tlfleet.cli.main import main as cli_main
from tlfleet.coordinator.report import figures
from tlfleet.coordinator.report.run_report import build_report, stl_goals, write_report

ROOT = Path(__file__).resolve().parents[2]
MAGIC = {"png": b"\x89PNG", "pdf": b"%PDF", "svg": b"<?xml"}


@pytest.mark.parametrize("fmt", ["pdf", "svg", "png"])
def test_every_format_is_written_and_found_again(tmp_path: Path, fmt: str) -> None:
    write_synthetic(tmp_path)
    report = write_report(tmp_path, figure_format=fmt)
    assert report.figures and all(p.suffix == f".{fmt}" for p in report.figure_paths)
    for path in report.figure_paths:
        assert path.read_bytes()[:len(MAGIC[fmt])] == MAGIC[fmt], path
    assert set(build_report(tmp_path).figures) == set(report.figures)
    assert f"]({report.figures[0]})" in (tmp_path / "report.md").read_text()


def test_svg_text_is_mathtext_and_the_format_flag(tmp_path: Path, capsys) -> None:
    write_synthetic(tmp_path)
    assert cli_main(["report", str(tmp_path), "--figure-format", "svg"]) == 0
    svg = next(tmp_path.glob("robustness_r*.svg")).read_text()
    assert "ρ^ψ" not in svg  # the literal caret title is gone: drawn as math
    with pytest.raises(ValueError, match="figure format 'gif'"):
        write_report(tmp_path, figure_format="gif")


def test_stl_goals_are_the_constant_points_of_the_tasks() -> None:
    s1 = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    assert sorted(stl_goals(s1, (0.0, 30.0))) == [(3, 0.0, -2.0, 0.1), (5, 0.0, 2.0, 0.1)]
    assert sorted(stl_goals(s1, (30.0, 90.0))) == [(3, 1.5, -1.5, 0.1), (4, 2.0, 2.0, 0.1),
                                                   (5, -1.0, 0.5, 0.1)]
    for name in ("scenario2", "scenario3"):  # robot-to-robot tasks only: no fixed goal
        scenario = load_scenario(ROOT / "scenarios" / f"{name}.toml")
        assert stl_goals(scenario, (0.0, scenario.duration)) == []


def test_each_robot_has_its_own_colour_map() -> None:
    first = [figures.robot_colormap(i)(1.0) for i in range(5)]
    assert len({tuple(np.round(c, 3)) for c in first}) == 5
    cmap = figures.robot_colormap(0)  # intensity grows with time: darker at the end
    assert sum(cmap(1.0)[:3]) < sum(cmap(0.0)[:3])
