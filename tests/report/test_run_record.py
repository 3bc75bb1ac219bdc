"""The typed run record (tlfleet.coordinator.record.run_record): summary.json and report.json are
written from RunSummary and Report and read back into equal records; report.json of schema 3
(Scenario 1's, committed in fixtures/s1-report-v3 as an earlier tlfleet wrote it, with the
markdown and console table it rendered) still reads and renders the same text; a file that does
not fit names the field."""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import pytest
from test_report import write_synthetic
from tlfleet.coordinator.record import rundir
from tlfleet.coordinator.record.run_record import (
    REPORT_SCHEMA,
    Detection,
    FaultRow,
    RecordError,
    Report,
    RunSummary,
    read_report,
    read_summary,
    write_record,
)
from tlfleet.coordinator.record.typed_json import from_json, to_json
from tlfleet.coordinator.report.render import render_markdown, render_table
from tlfleet.coordinator.report.run_report import build_report
from tlfleet.coordinator.report.summary import summarise_run

FIXTURES = Path(__file__).resolve().parent / "fixtures"
V3 = FIXTURES / "s1-report-v3"


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    """The synthetic run of test_report and copies of the thinned Scenario 1–3 runs."""
    out = {}
    synthetic = tmp_path_factory.mktemp("synthetic")
    write_synthetic(synthetic)
    out["synthetic"] = synthetic
    for name in ("s1", "s2", "s3"):
        run_dir = tmp_path_factory.mktemp(name)
        shutil.copytree(FIXTURES / name, run_dir, dirs_exist_ok=True)
        out[name] = run_dir
    return out


@pytest.mark.parametrize("name", ["synthetic", "s1", "s2", "s3"])
def test_summary_and_report_round_trip_through_their_files(runs, name, tmp_path) -> None:
    _text, summary = summarise_run(runs[name])
    write_record(tmp_path / "summary.json", summary)
    assert read_summary(tmp_path / "summary.json") == summary
    report = build_report(runs[name], summary)
    write_record(tmp_path / "report.json", report)
    back = read_report(tmp_path / "report.json")
    assert back == report
    assert render_markdown(back) == render_markdown(report)
    assert render_table(back) == render_table(report)
    data = json.loads((tmp_path / "report.json").read_text())
    assert data["schema"] == REPORT_SCHEMA and list(data)[1:] == [
        f for f in Report.__dataclass_fields__]  # one key per field, in order


def test_non_finite_robustness_survives_the_file(runs, tmp_path) -> None:
    """An empty window's ρ is ±inf: written as "inf"/"-inf" (JSON has no infinity), read back
    as the float."""
    _text, summary = summarise_run(runs["synthetic"])
    first = summary.stl[3].subtasks[0]
    edited = replace(summary, stl={**summary.stl, 3: replace(summary.stl[3], subtasks=(
        replace(first, robustness=-math.inf), *summary.stl[3].subtasks[1:]))})
    write_record(tmp_path / "summary.json", edited)
    assert '"robustness": "-inf"' in (tmp_path / "summary.json").read_text()
    assert read_summary(tmp_path / "summary.json").stl[3].subtasks[0].robustness == -math.inf


def test_schema_3_report_of_scenario_1_renders_the_same_tables() -> None:
    report = read_report(V3 / "report.json")
    assert json.loads((V3 / "report.json").read_text())["schema"] == 3
    assert render_markdown(report) == (V3 / "report.md").read_text(encoding="utf-8")
    assert render_table(report) + "\n" == (V3 / "table.txt").read_text(encoding="utf-8")
    # schema 3 wrote a detection without after_wall/by and a death as its event's data: the
    # record reads them with the defaults that mean "absent"
    fault = {"spec": "kill:robot3@5", "kind": "kill", "targets": ["agent-3"], "start_t": 5.0,
             "end_t": 5.0, "lasted": 0.0, "error": None, "min_clearance": 0.2,
             "detection": {"kind": "process_died", "t": 5.2, "after_sim": 0.2}}
    assert from_json(FaultRow, fault).detection == Detection("process_died", 5.2, 0.2)


@pytest.mark.parametrize(("edit", "message"), [
    (lambda d: d.update(schema=2), r"schema: report\.json schema 2: this tlfleet reads 3 and 4"),
    (lambda d: d.pop("schema"), r"schema None"),
    (lambda d: d["stl"]["4"]["subtasks"][1].update(r_bar="low"),
     r"stl\.4\.subtasks\[1\]\.r_bar: expected a number, got str 'low'"),
    (lambda d: d["ltl"]["1"].pop("accepting"), r"ltl\.1\.accepting: missing"),
    (lambda d: d["stl"].update({"four": d["stl"]["4"]}), r"stl: expected an integer key"),
    (lambda d: d["tasks"]["results"][0].update(outcome="fine"),
     r"tasks\.results\[0\]\.outcome: expected one of"),
    (lambda d: d.update(closest_approach={"pair": [3], "gap": 0.1, "t": 2.0}),
     r"closest_approach\.pair: expected 2 items, got 1"),
])
def test_a_report_that_does_not_fit_names_the_file_and_field(tmp_path, edit, message) -> None:
    data = json.loads((V3 / "report.json").read_text())
    edit(data)
    path = tmp_path / "report.json"
    path.write_text(json.dumps(data))
    with pytest.raises(RecordError, match=message) as caught:
        read_report(path)
    assert str(caught.value).startswith(str(path))


def test_a_missing_or_torn_file_is_a_record_error(tmp_path) -> None:
    with pytest.raises(RecordError, match="missing, unreadable or not JSON"):
        read_summary(tmp_path / "summary.json")
    (tmp_path / "summary.json").write_text('{"schema": 1, "scenario": "s')
    with pytest.raises(RecordError, match="not JSON"):
        read_summary(tmp_path / "summary.json")


def test_summary_json_has_a_schema_and_no_copy_of_run_json(runs, tmp_path) -> None:
    run_dir = tmp_path / "run"
    shutil.copytree(runs["s1"], run_dir)
    from tlfleet.coordinator.report.summary import write_summary

    _text, summary = write_summary(run_dir)
    data = json.loads((run_dir / rundir.SUMMARY_JSON).read_text())
    info = json.loads((run_dir / rundir.RUN_INFO).read_text())
    assert data["schema"] == 1 and "run" not in data
    assert (data["mode"], data["wall_time"]) == (info["mode"], info["wall_time"])
    assert rundir.json_ready(to_json(summary)) == data
    assert from_json(RunSummary, data) == summary
