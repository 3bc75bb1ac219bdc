"""One table of every benchmark figure with a target (issue 17 item 6): read the JSON files the
benchmarks wrote under ``bench/results/`` and print value (CPU where timed), wall, target and met.

    .venv/bin/python bench/summary.py [bench/results]
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


Row = tuple[str, str, str, str, str, str]


def _when(data: dict) -> str:
    """The load average before the run and, where the file has it, the hour it ran (UTC): this
    shared machine's speed moves every multi-process figure from one hour to the next."""
    load = data.get("load_average_before", [math.nan])[0]
    stamp = data.get("time_utc")
    return f"(load {load:.1f}, {stamp[11:16]}Z)" if isinstance(stamp, str) and len(stamp) >= 16 \
        else f"(load {load:.1f})"


def _figure_rows(name: str, data: dict, when: str) -> list[Row]:
    """The common layout (``bench/common.py``: ``figures``)."""
    out = []
    for f in data["figures"]:
        value = "n/a" if f["value"] is None or not math.isfinite(f["value"]) \
            else f"{f['value']:.3g} {f['unit']}"
        wall = "-" if f.get("wall") is None else f"{f['wall']:.3g} {f['unit']}"
        target = "-" if f["target"] is None else \
            f"{'≤' if f['better'] == 'lower' else '≥'} {f['target']:g} {f['unit']}"
        met = "" if f["met"] is None else "met" if f["met"] else "NOT MET"
        out.append((name, f["label"].strip(), value, wall, target,
                    f"{met}  {when}" if met else ""))
    return out


def _nav_rows(name: str, data: dict, when: str) -> list[Row]:
    """``nav_bench``'s own layout: ``results`` per case in ms, ``targets_ms``."""
    out = []
    for key, ok in data["meets_targets"].items():
        r = data["results"][key]
        out.append((name, key, f"{r.get('cpu_median_ms', math.nan):.3g} ms",
                    f"{r['median_ms']:.3g} ms", f"≤ {data['targets_ms'][key]:g} ms",
                    f"{'met' if ok else 'NOT MET'}  {when}"))
    return out


def rows(results: Path) -> tuple[list[Row], list[str]]:
    """Every figure of every ``*_bench.json`` under ``results``, and the problems met: a file
    that is not JSON or not in a known layout is named, not skipped in silence."""
    out: list[Row] = []
    problems: list[str] = []
    for path in sorted(results.glob("*_bench.json")):
        try:
            data = json.loads(path.read_text())
            name = data.get("benchmark", path.stem)
            when = _when(data)
            if "figures" in data:
                out += _figure_rows(name, data, when)
            elif "targets_ms" in data:
                out += _nav_rows(name, data, when)
            else:  # outcome tables without timing targets (fleet_bench, scenario_bench)
                out.append((name, f"no timed figures here: see {path.name}", "", "", "", ""))
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            problems.append(f"{path}: {type(exc).__name__}: {exc}")
    return out, problems


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    results = Path(args[0]) if args else ROOT / "bench" / "results"
    table, problems = rows(results)
    print(f"== every benchmark figure ({results})")
    print(f"{'bench':<14} {'measure':<58} {'value (CPU)':>13} {'wall':>12} {'target':>14}  met")
    for bench, label, value, wall, target, met in table:
        print(f"{bench:<14} {label:<58} {value:>13} {wall:>12} {target:>14}  {met}")
    for problem in problems:
        print(f"unreadable: {problem}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
