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


def rows(results: Path) -> list[tuple[str, str, str, str, str, str]]:
    out = []
    for path in sorted(results.glob("*_bench.json")):
        data = json.loads(path.read_text())
        load = data.get("load_average_before", [math.nan])[0]
        for f in data.get("figures", []):
            value = "n/a" if f["value"] is None or not math.isfinite(f["value"]) \
                else f"{f['value']:.3g} {f['unit']}"
            wall = "-" if f.get("wall") is None else f"{f['wall']:.3g} {f['unit']}"
            target = "-" if f["target"] is None else \
                f"{'≤' if f['better'] == 'lower' else '≥'} {f['target']:g} {f['unit']}"
            met = "" if f["met"] is None else "met" if f["met"] else "NOT MET"
            out.append((data.get("benchmark", path.stem), f["label"].strip(), value, wall,
                        target, f"{met}  (load {load:.1f})" if met else ""))
        if "figures" not in data and "meets_targets" in data:  # nav_bench's own layout
            for key, ok in data["meets_targets"].items():
                r = data["results"][key]
                out.append((data.get("benchmark", path.stem), key,
                            f"{r.get('cpu_median_ms', math.nan):.3g} ms",
                            f"{r['median_ms']:.3g} ms", f"≤ {data['targets_ms'][key]:g} ms",
                            f"{'met' if ok else 'NOT MET'}  (load "
                            f"{data.get('load_average_before', [math.nan])[0]:.1f})"))
    return out


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    results = Path(args[0]) if args else ROOT / "bench" / "results"
    table = rows(results)
    print(f"== every benchmark figure ({results})")
    print(f"{'bench':<14} {'measure':<58} {'value (CPU)':>13} {'wall':>12} {'target':>14}  met")
    for bench, label, value, wall, target, met in table:
        print(f"{bench:<14} {label:<58} {value:>13} {wall:>12} {target:>14}  {met}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
