"""``tlfleet report``, ``replay`` and ``monitor`` on damaged run directories: one line on stderr,
no traceback, a non-zero exit — whatever file is damaged and however (binary bytes, JSON nested
beyond Python's recursion limit, wrong types where numbers are read, a CSV field past the csv
module's limit, a directory where a file is written, NaN times). A directory that is whole exits
0, so the damage is what the exit code says."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from tlfleet.cli.main import main

FIXTURE = Path(__file__).resolve().parent / "fixtures" / "s1"
DEEP = "[" * 100_000 + "]" * 100_000
JUNK = bytes(range(256)) * 8


def _nan_row(path: Path) -> str:
    lines = path.read_text().splitlines()
    lines[3] = ",".join(["nan"] * len(lines[3].split(",")))
    return "\n".join(lines) + "\n"


DAMAGE = {  # name: (file, what it becomes)
    "run.json deep": ("run.json", DEEP),
    "run.json binary": ("run.json", JUNK),
    "run.json types": ("run.json", json.dumps({"malformed_received": {"x": "abc"},
                                               "wall_time": "long", "mode": 3})),
    "events deep": ("events.jsonl", '{"t": 1, "source": "sim", "kind": "x", "data": '
                    + '{"a":' * 100_000 + "1" + "}" * 100_000 + "}\n"),
    "events sim_stats types": ("events.jsonl", json.dumps(
        {"t": 1.0, "source": "sim", "kind": "sim_stats",
         "data": {"due": "many", "missed": "x"}}) + "\n"),
    "events fault types": ("events.jsonl", json.dumps(
        {"t": 1.0, "source": "coordinator", "kind": "fault_start",
         "data": {"spec": [1], "targets": 5, "wall": "x"}}) + "\n"),
    "events binary": ("events.jsonl", JUNK),
    "trajectory binary": ("trajectory.csv", JUNK),
    "trajectory huge field": ("trajectory.csv", "t," + "x" * 1_000_000 + "\n1,2\n"),
    "trajectory NaN time": ("trajectory.csv", _nan_row),
    "status binary": ("status.csv", JUNK),
    "scenario binary": ("scenario.toml", JUNK),
    "scenario deep": ("scenario.toml", "x = " + DEEP + "\n"),
    "report.md a directory": ("report.md", "DIR"),
}


def damaged(tmp_path: Path, name: str) -> Path:
    run = tmp_path / "run"
    shutil.copytree(FIXTURE, run)
    file, content = DAMAGE[name]
    path = run / file
    if content == "DIR":
        path.unlink(missing_ok=True)
        path.mkdir()
    elif callable(content):
        path.write_text(content(path))
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return run


def run_cli(capsys, *argv: str) -> tuple[int, list[str]]:
    code = main(list(argv))
    err = capsys.readouterr().err
    return code, [line for line in err.splitlines() if line.strip()]


def commands(run: Path) -> dict[str, tuple[str, ...]]:
    return {"report": ("report", str(run), "--no-figures"),
            "replay": ("replay", str(run), "-o", str(run.parent / "x.rrd")),
            "monitor": ("monitor", str(run / "scenario.toml"), str(run / "trajectory.csv"))}


def test_a_whole_run_directory_exits_0(tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(FIXTURE, run)
    for name, argv in commands(run).items():
        code, err = run_cli(capsys, *argv)
        assert code == 0 and not any("Traceback" in e for e in err), (name, err)


@pytest.mark.parametrize("name", DAMAGE)
def test_a_damaged_run_directory_is_one_line_and_not_zero(tmp_path, capsys, name):
    run = damaged(tmp_path, name)
    file = DAMAGE[name][0]
    for command, argv in commands(run).items():
        if command == "monitor" and file not in ("trajectory.csv", "scenario.toml"):
            continue  # monitor reads only these two
        if command != "report" and file == "report.md":
            continue  # only report writes it
        code, err = run_cli(capsys, *argv)
        assert code != 0, (command, err)
        assert len(err) == 1 and err[0].startswith(f"tlfleet {command}: "), (command, err)
