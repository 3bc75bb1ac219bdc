"""Regenerate ``tests/report/fixtures/s1..s3`` from full run directories (not a test).

    .venv/bin/python tests/report/make_fixtures.py /tmp/samples

Each fixture is a real ``tlfleet run`` directory of the paper's scenario (lockstep), thinned to
stay small: ``trajectory.csv`` keeps every ``TRAJ_STEP``-th frame (100 Hz → 2 Hz) and the last,
with 3 decimals (1 mm); ``status.csv`` keeps every ``STATUS_STEP``-th STL row per robot (1 Hz),
every LTL row where the plan, visits, rounds or mode change, and the last rows, numbers rounded to 4
decimals; ``events.jsonl`` drops the kinds the report does not read (``DROPPED_EVENTS``) and keeps
``stage``, ``r`` and ``subtask`` of ``repair`` events; ``scenario.toml`` and ``run.json`` are
copied unchanged. The tests recompute everything from the
thinned files, so the thinning changes numbers but not what is checked.

``fixtures/s1-report-v3`` is different: ``report.json`` as tlfleet wrote it at report schema 3
from ``fixtures/s1`` (run directory renamed ``runs/scenario1-fixture``, the figure names put in),
with the ``report.md`` and console table (``table.txt``) that version rendered from it. It is
never rewritten: the test reads that old JSON with today's record and renderer. After a
deliberate change of the rendered text, re-render the two text files from it:

    .venv/bin/python tests/report/make_fixtures.py --render-report-v3
"""

from __future__ import annotations

import csv
import json
import shutil
import sys
from pathlib import Path

TRAJ_STEP = 50
STATUS_STEP = 10
DROPPED_EVENTS = {"critical_event", "agent_stats"}
HERE = Path(__file__).resolve().parent / "fixtures"
LTL_KEYS = ("prefix", "suffix", "visits", "rounds", "mode")


def _round(cell: str, digits: int = 4) -> str:
    try:
        value = float(cell)
    except ValueError:
        return cell
    text = f"{value:.{digits}f}".rstrip("0").rstrip(".")
    return cell if cell.isdigit() else ("0" if text in ("", "-0") else text)


def _thin_events(source: Path, target: Path) -> None:
    lines = []
    for line in source.read_text(encoding="utf-8").splitlines():
        event = json.loads(line)
        if event.get("kind") in DROPPED_EVENTS:
            continue
        if event.get("kind") == "repair":
            data = event["data"]
            event["data"] = {"stage": data.get("stage"), "r": round(data.get("r"), 5),
                             "subtask": data.get("subtask")}
        lines.append(json.dumps(event, ensure_ascii=False, separators=(",", ":")))
    target.write_text("\n".join(lines) + "\n", encoding="utf-8")


def thin(source: Path, target: Path) -> None:
    target.mkdir(parents=True, exist_ok=True)
    for name in ("scenario.toml", "run.json"):
        shutil.copyfile(source / name, target / name)
    _thin_events(source / "events.jsonl", target / "events.jsonl")
    with open(source / "trajectory.csv", newline="") as f:
        rows = list(csv.reader(f))
    body = rows[1:]
    keep = body[::TRAJ_STEP] + ([body[-1]] if (len(body) - 1) % TRAJ_STEP else [])
    with open(target / "trajectory.csv", "w", newline="") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(rows[0])
        writer.writerows([[_round(c, 3) for c in row] for row in keep])
    with open(source / "status.csv", newline="") as f:
        reader = csv.DictReader(f)
        header, statuses = reader.fieldnames, list(reader)
    kept, seen, last = [], {}, {}
    for row in statuses:
        key = (row["robot"], row["kind"])
        n = seen.get(key, 0)
        seen[key] = n + 1
        last[key] = row
        if row["kind"] == "stl":
            if n % STATUS_STEP == 0:
                kept.append(row)
        elif n == 0 or tuple(row[k] for k in LTL_KEYS) != getattr(thin, "_prev", {}).get(key):
            kept.append(row)
        if row["kind"] == "ltl":
            thin._prev = {**getattr(thin, "_prev", {}), key: tuple(row[k] for k in LTL_KEYS)}
    kept += [row for row in last.values() if row not in kept]
    kept.sort(key=lambda r: float(r["t"]))
    thin._prev = {}
    with open(target / "status.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, header, lineterminator="\n")
        writer.writeheader()
        for row in kept:
            writer.writerow({k: (_round(v) if k in ("t", "rho", "rho_max", "lower", "r") else v)
                             for k, v in row.items()})


def render_report_v3() -> None:
    """``report.md`` and ``table.txt`` of ``s1-report-v3`` from its report.json, as rendered now."""
    from tlfleet.coordinator.record.run_record import read_report
    from tlfleet.coordinator.report.render import render_markdown, render_table

    folder = HERE / "s1-report-v3"
    report = read_report(folder / "report.json")
    (folder / "report.md").write_text(render_markdown(report), encoding="utf-8")
    (folder / "table.txt").write_text(render_table(report) + "\n", encoding="utf-8")


if __name__ == "__main__":
    if sys.argv[1:] == ["--render-report-v3"]:
        render_report_v3()
        sys.exit(0)
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/samples")
    for name in ("s1", "s2", "s3"):
        thin(root / name, HERE / name)
        size = sum(p.stat().st_size for p in (HERE / name).iterdir())
        print(f"{name}: {size / 1024:.0f} KiB")
