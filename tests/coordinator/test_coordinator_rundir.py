"""tlfleet.coordinator.record.rundir: the one reader and writer of a run directory. Each file is
opened once per command, status rows round-trip without JSON in cells, and the JSON edge keeps ±inf
and None."""

from __future__ import annotations

import builtins
import io
import json
import math
import shutil
from collections import Counter
from pathlib import Path

import pytest
from tlfleet.bus.protocol.messages import Event, LtlStatus, StlStatus
from tlfleet.coordinator.record import rundir
from tlfleet.coordinator.report.outputs import write_outputs
from tlfleet.coordinator.run import RunConfig

FIXTURES = Path(__file__).resolve().parents[1] / "report" / "fixtures"
RUN_FILES = (rundir.SCENARIO, rundir.RUN_INFO, rundir.TRAJECTORY, rundir.STATUS, rundir.EVENTS)


def _count_opens(monkeypatch) -> Counter[str]:
    """Count every open of a file, by name, through builtins.open, io.open and Path methods."""
    opened: Counter[str] = Counter()
    real_open = builtins.open

    def counting_open(file, mode="r", *args, **kwargs):
        if isinstance(file, str | Path) and "r" in mode:
            opened[Path(file).name] += 1
        return real_open(file, mode, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", counting_open)
    monkeypatch.setattr(io, "open", counting_open)
    return opened


def test_the_end_of_a_run_reads_each_file_once(tmp_path, monkeypatch):
    """Summary, report (with figures) and run.rrd after a run: one read of each file."""
    run = tmp_path / "s1"
    shutil.copytree(FIXTURES / "s1", run)
    from tlfleet.agent.scenario import load_scenario

    scenario = load_scenario(run / rundir.SCENARIO)
    opened = _count_opens(monkeypatch)
    config = RunConfig(scenario_path=run / rundir.SCENARIO, report=True, figures=True, rrd=True)
    info: dict = {}
    _text, _data, report, rrd, _verdict, tally = write_outputs(
        run, scenario, config, info, lambda _info: None, lambda _t: None, lambda t: pytest.fail(t))
    assert report is not None and report.figures and rrd == run / rundir.RRD
    assert tally is not None and info["tasks"] == tally.to_json()
    assert {name: opened[name] for name in RUN_FILES} == {
        rundir.SCENARIO: 0,  # the runner's loaded scenario is reused
        rundir.RUN_INFO: 1, rundir.TRAJECTORY: 1, rundir.STATUS: 1, rundir.EVENTS: 1}
    assert (run / rundir.SUMMARY_JSON).is_file() and (run / rundir.REPORT_JSON).is_file()


def test_status_rows_round_trip_with_tokens_not_json(tmp_path):
    stl = StlStatus(3, 1.25, 1, 0.05, math.nan, -0.2, 0.08, 2, 1, 1, 4, (2, 1, 0))
    ltl = LtlStatus(1, 1.4, ("start", "a11"), ("a12", "a11"), None, (0, 2),
                    (("a11", 2), ("a_1", 10)), 1, "navigate")
    writer = rundir.StatusWriter(tmp_path / rundir.STATUS)
    writer.write(stl)
    writer.write(ltl)
    writer.handle.close()
    text = (tmp_path / rundir.STATUS).read_text()
    assert "[" not in text and "{" not in text
    back = rundir.read_statuses(tmp_path / rundir.STATUS)
    assert back[1] == ltl
    assert back[0].events == stl.events and math.isnan(back[0].rho_max)
    assert (back[0].robot, back[0].t, back[0].subtask, back[0].r) == (3, 1.25, 1, 0.08)


def test_legacy_json_cells_still_read():
    statuses = rundir.read_statuses(FIXTURES / "s1" / rundir.STATUS)
    ltl = [s for s in statuses if isinstance(s, LtlStatus)]
    stl = [s for s in statuses if isinstance(s, StlStatus)]
    assert ltl and stl and ltl[-1].suffix and len(stl[-1].events) == 3


@pytest.mark.parametrize(("line", "reason"), [
    ('{"t": "x", "source": "sim", "kind": "k", "data": {}}\n', "'t' must be a number"),
    ('[1, 2]\n', "not a JSON object"),
    ('{"t": 1, "source": 3, "kind": "k"}\n', "must be strings"),
])
def test_a_bad_event_line_is_an_error_when_strict_and_a_problem_when_lenient(tmp_path, line,
                                                                               reason):
    path = tmp_path / rundir.EVENTS
    path.write_text(rundir.event_line(Event(0.5, "sim", "sim_done", {})) + line)
    with pytest.raises(rundir.RunFileError, match=rf"events.jsonl:2: .*{reason}"):
        rundir.read_events(path)
    problems: list[rundir.Problem] = []
    assert len(rundir.read_events(path, strict=False, problems=problems)) == 1
    assert [(p.file, p.line, p.torn) for p in problems] == [(rundir.EVENTS, 2, False)]


def test_the_json_edge_keeps_infinities_and_missing_values(tmp_path):
    path = tmp_path / "x.json"
    rundir.write_json(path, {"g": math.inf, "f": -math.inf, "nan": math.nan, "t": (1, 2.5),
                             "n": None, 3: "key"})
    assert json.loads(path.read_text()) == {"g": "inf", "f": "-inf", "nan": None, "t": [1, 2.5],
                                            "n": None, "3": "key"}
