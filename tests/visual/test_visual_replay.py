"""``tlfleet replay``: the .rrd reads back with rerun's own reader; bad inputs fail clearly."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from tlfleet.cli.main import main
from tlfleet.coordinator.record.rundir import read_events, read_statuses
from visual_helpers import N_FRAMES, T0, T1, pose, read_rrd, write_run

EXPECTED = {
    "/world", "/world/arena", "/world/regions", "/world/robots", "/world/headings",
    "/world/trails", "/world/plans/r1", "/world/plans/r1/target",
    "/rho/r2/rho", "/rho/r2/rho_max", "/rho/r2/lower", "/rho/r2/r",
    "/rho/r2/critical", "/rho/r2/repairs",
    "/events/r1", "/events/r2", "/events/sim",
}


def test_replay_writes_an_rrd_that_reads_back(run_dir: Path, capsys) -> None:
    assert main(["replay", str(run_dir)]) == 0
    out = capsys.readouterr().out
    assert f"{run_dir / 'run.rrd'}: 51 frames" in out
    rrd = read_rrd(run_dir / "run.rrd")
    entities = set(rrd["rows"]) - {"/__properties"}
    assert entities >= EXPECTED
    assert not any(e.startswith("/rho/r1") for e in entities)  # robot 1 is an LTL robot
    assert "sim_time" in rrd["timelines"]
    assert rrd["t_range"] == pytest.approx((T0, T1), abs=1e-6)
    # every 5th of 251 rows = rows 0, 5, …, 250: 51 frames, the last one included
    assert rrd["timed"]["/world/robots"] == 51
    assert rrd["timed"]["/world/headings"] == 51
    # 26 statuses per robot, the first two STL ones idle (NaN, not logged)
    assert rrd["timed"]["/rho/r2/rho"] == 24
    # the plan is logged once, the target when it changes (a1, then a2)
    assert rrd["timed"]["/world/plans/r1"] == 1
    assert rrd["timed"]["/world/plans/r1/target"] == 2
    assert rrd["timed"]["/rho/r2/critical"] == 1 and rrd["timed"]["/rho/r2/repairs"] == 1


def test_replay_logs_the_recorded_poses(run_dir: Path) -> None:
    assert main(["replay", str(run_dir), "--every", "1", "--out", str(run_dir / "all.rrd")]) == 0
    rrd = read_rrd(run_dir / "all.rrd")
    assert rrd["timed"]["/world/robots"] == N_FRAMES
    batch = rrd["batches"]["/world/robots"][-1]
    last = batch.column("Points2D:positions").to_pylist()[-1]
    times = batch.column("sim_time").cast("int64").to_pylist()
    assert times[-1] == round(T1 * 1e9)
    np.testing.assert_allclose(np.array(last), [pose(1, T1)[:2], pose(2, T1)[:2]], atol=1e-6)
    arrows = rrd["batches"]["/world/headings"][-1].column("Arrows2D:vectors").to_pylist()[-1]
    np.testing.assert_allclose(np.array(arrows), [
        [0.32 * math.cos(pose(r, T1)[2]), 0.32 * math.sin(pose(r, T1)[2])] for r in (1, 2)],
        atol=1e-6)  # 1.6 radii along θ
    static = rrd["static"]["/world/robots"][0]
    assert static.column("Points2D:labels").to_pylist() == [["1 LTL", "2 STL"]]
    assert static.column("Points2D:radii").to_pylist() == [[pytest.approx(0.2)] * 2]
    rho = rrd["batches"]["/rho/r2/repairs"][0].column("Scalars:scalars").to_pylist()
    assert rho == [[pytest.approx(0.15)]]  # the r̄ of the repair event


def test_status_and_event_files_read_back_as_the_messages_written(run_dir: Path) -> None:
    written = write_run(run_dir.parent / "again")
    statuses = read_statuses(run_dir.parent / "again" / "status.csv")
    assert len(statuses) == len(written["statuses"])
    for got, want in zip(statuses, written["statuses"], strict=True):
        assert type(got) is type(want)
        for name in want.__slots__:
            a, b = getattr(got, name), getattr(want, name)
            assert (math.isnan(a) and math.isnan(b)) if isinstance(b, float) and math.isnan(b) \
                else a == b, name
    assert read_events(run_dir.parent / "again" / "events.jsonl") == written["events"]


def _break(path: Path, line: int, text: str) -> None:
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    lines[line - 1] = text
    path.write_text("".join(lines), encoding="utf-8")


BAD_INPUTS = [
    # (what to do to the copy, file named in the message, words in the message)
    ("no_scenario", "scenario.toml", "missing"),
    ("no_trajectory", "trajectory.csv", "cannot open"),
    ("no_status", "status.csv", "missing"),
    ("no_events", "events.jsonl", "missing"),
    ("bad_trajectory_row", "trajectory.csv:5", "not a number"),
    ("trajectory_other_robots", "trajectory.csv", "do not match the scenario"),
    ("bad_status_row", "status.csv:3", "could not convert"),
    ("bad_status_kind", "status.csv:2", "kind must be"),
    ("bad_status_header", "status.csv:1", "lacks the column"),
    ("bad_event_json", "events.jsonl:2", "Expecting"),
    ("bad_event_data", "events.jsonl:1", "'data' must be an object"),
    ("bad_scenario", "scenario.toml", ""),
]


def _damage(run: Path, how: str) -> None:
    if how.startswith("no_"):
        name = {"no_scenario": "scenario.toml", "no_trajectory": "trajectory.csv",
                "no_status": "status.csv", "no_events": "events.jsonl"}[how]
        (run / name).unlink()
    elif how == "bad_trajectory_row":
        _break(run / "trajectory.csv", 5, "0.54,1.0,oops,0.0,0.0,0.0,0.0\n")
    elif how == "trajectory_other_robots":
        text = (run / "trajectory.csv").read_text().replace("x2,y2,th2", "x3,y3,th3", 1)
        (run / "trajectory.csv").write_text(text)
    elif how == "bad_status_row":
        header = (run / "status.csv").read_text().splitlines()[0].split(",")
        row = ["0.6", "2", "stl", "0", "abc"] + [""] * (len(header) - 5)
        _break(run / "status.csv", 3, ",".join(row) + "\n")
    elif how == "bad_status_kind":
        lines = (run / "status.csv").read_text().splitlines(keepends=True)
        _break(run / "status.csv", 2, lines[1].replace(",ltl,", ",xyz,", 1))
    elif how == "bad_status_header":
        _break(run / "status.csv", 1, "t,robot,kind\n")
    elif how == "bad_event_json":
        _break(run / "events.jsonl", 2, "{not json\n")
    elif how == "bad_event_data":
        _break(run / "events.jsonl", 1, '{"t": 0.5, "source": "sim", "kind": "x", "data": 3}\n')
    elif how == "bad_scenario":
        (run / "scenario.toml").write_text("name = 3\n")


@pytest.mark.parametrize(("how", "where", "words"), BAD_INPUTS, ids=[b[0] for b in BAD_INPUTS])
def test_bad_inputs_exit_1_naming_the_file_and_write_nothing(copy_run, capsys, how, where,
                                                              words) -> None:
    run = copy_run(how)
    (run / "run.rrd").write_bytes(b"previous")
    _damage(run, how)
    assert main(["replay", str(run)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("tlfleet replay: ")
    assert len(err.splitlines()) == 1, err
    assert str(run / where) in err and words in err
    assert (run / "run.rrd").read_bytes() == b"previous"  # not clobbered


def test_a_missing_run_directory_is_one_line(tmp_path: Path, capsys) -> None:
    assert main(["replay", str(tmp_path / "nope")]) == 1
    err = capsys.readouterr().err.strip()
    assert err == f"tlfleet replay: {tmp_path / 'nope'}: not a run directory"


def test_a_torn_last_event_line_is_skipped(copy_run) -> None:
    run = copy_run("torn")
    with open(run / "events.jsonl", "a", encoding="utf-8") as handle:
        handle.write('{"t": 3.0, "source": "ag')  # a crash mid-write: no newline
    assert len(read_events(run / "events.jsonl")) == 4
    assert main(["replay", str(run)]) == 0
    assert read_rrd(run / "run.rrd")["timed"]["/world/robots"] == 51


def test_every_must_be_positive(run_dir: Path) -> None:
    with pytest.raises(SystemExit):
        main(["replay", str(run_dir), "--every", "0"])
