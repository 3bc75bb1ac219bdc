"""The viewer's layout for people: no label on top of another (the target's label beside its
region, not on the region's name), the STL goals drawn with their windows, one time range and no
legend over the data in every ρ panel."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from tlfleet.agent.scenario import load_scenario
from tlfleet.cli.main import main
from tlfleet.coordinator.report import viewer
from visual_helpers import SCENARIO, read_rrd

ROOT = Path(__file__).resolve().parents[2]


def test_the_target_label_stands_apart_from_the_region_name(run_dir: Path) -> None:
    assert main(["replay", str(run_dir)]) == 0
    rrd = read_rrd(run_dir / "run.rrd")
    scenario = load_scenario(SCENARIO)
    centres = {r.name: np.array(r.center) for r in scenario.regions}
    names = rrd["static"]["/world/regions/names"][0]
    name_at = dict(zip(names.column("Points2D:labels").to_pylist()[0],
                       map(np.array, names.column("Points2D:positions").to_pylist()[0]),
                       strict=True))
    seen = 0
    for batch in rrd["batches"]["/world/plans/r1/target/label"]:
        for labels, positions in zip(batch.column("Points2D:labels").to_pylist(),
                                     batch.column("Points2D:positions").to_pylist(),
                                     strict=True):
            (label,), (position,) = labels, positions
            region = label.split("→")[1].strip()
            gap = np.linalg.norm(np.array(position) - name_at[region])
            # a label is ~0.3 m tall at the arena's scale: at least that far from the name
            assert gap >= 0.3, (label, gap)
            assert np.allclose(name_at[region], centres[region])
            seen += 1
    assert seen == 2  # a1, then a2


def test_stl_goals_in_the_viewer_name_robot_and_window() -> None:
    scenario = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    goals = viewer.stl_goals(scenario)
    assert sorted(label for *_rest, label in goals) == [
        "goal 3 [21, 30] s", "goal 3 [57, 58] s", "goal 4 [83, 87] s", "goal 5 [21, 30] s",
        "goal 5 [44, 47] s"]
    assert (3, 1.5, -1.5, pytest.approx(0.1), "goal 3 [57, 58] s") in goals


def _views(container):
    for item in getattr(container, "contents", []):
        if hasattr(item, "properties"):
            yield item
        else:
            yield from _views(item)


def test_every_rho_panel_shares_the_runs_time_range_without_a_legend() -> None:
    scenario = load_scenario(ROOT / "scenarios" / "scenario1.toml")
    panels = [v for v in _views(viewer.blueprint(scenario).root_container)
              if "VisibleTimeRanges" in v.properties and "PlotLegend" in v.properties]
    assert len(panels) == sum(r.is_stl for r in scenario.robots)
    span = f"'end': {round(scenario.duration * 1e9)}, 'start': 0"
    for view in panels:
        assert span in repr(view.properties["VisibleTimeRanges"])  # [0, duration] in every one
        assert "visible=[False]" in repr(view.properties["PlotLegend"])
