"""The broken-scenario corpus through the loader of a tlfleet tree: specific / vague / crash /
accepted per case (issue 11's before/after table).

    python bench/scenario_corpus.py                      # this tree
    python bench/scenario_corpus.py --root /tmp/base     # another checkout (e.g. main's)

Each case (``tests/scenario/broken_corpus.py``) is written to a temporary directory and loaded
by ``tlfleet.agent.scenario.load_scenario`` of ``--root`` in its own subprocess (30 s timeout, 2 GiB
address-space limit, so /dev/zero or a hang cannot take the machine down):

* **specific** — a ``ScenarioError`` naming the expected field path with the expected reason;
* **vague** — a ``ScenarioError``, but of another field or reason (e.g. a misspelt key reported as
  a *missing* one);
* **crash** — any other exception (a traceback for the user), a timeout or a kill;
* **accepted** — the file loaded as a valid scenario.

Prints the table and writes ``bench/results/scenario_corpus-<label>.json``.
"""

from __future__ import annotations

import argparse
import json
import re
import resource
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT / "tests" / "scenario"))

from broken_corpus import CASES  # noqa: E402

LOADER = """
import json, sys
sys.setrecursionlimit(1000)
try:
    from tlfleet.bus.errors import ScenarioError
    from tlfleet.agent.scenario import load_scenario
    try:
        load_scenario(sys.argv[1])
        print(json.dumps({"status": "accepted"}))
    except ScenarioError as exc:
        print(json.dumps({"status": "error", "field": exc.field, "reason": exc.reason[:300]}))
except BaseException as exc:
    print(json.dumps({"status": "crash", "error": f"{type(exc).__name__}: {str(exc)[:200]}"}))
"""


def _limits() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))


def classify(root: Path, case, tmp: Path) -> dict:
    path = case.make(tmp)
    began = time.monotonic()
    try:
        proc = subprocess.run([sys.executable, "-c", LOADER, str(path)], cwd=root,
                              capture_output=True, text=True, timeout=30,
                              env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"},
                              preexec_fn=_limits)
        lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
        result = json.loads(lines[-1]) if lines else {
            "status": "crash", "error": f"exit {proc.returncode}: {proc.stderr[-200:]}"}
    except subprocess.TimeoutExpired:
        result = {"status": "crash", "error": "timeout (30 s)"}
    result["seconds"] = round(time.monotonic() - began, 2)
    if result["status"] == "error":
        ok = result["field"] == case.field and re.search(case.reason, result["reason"])
        result["class"] = "specific" if ok else "vague"
    else:
        result["class"] = result["status"]
    return result


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--root", type=Path, default=ROOT)
    parser.add_argument("--label", default=None)
    args = parser.parse_args()
    label = args.label or ("after" if args.root.resolve() == ROOT else "before")
    rows = []
    for case in CASES:
        with tempfile.TemporaryDirectory() as tmp:
            result = classify(args.root.resolve(), case, Path(tmp))
        rows.append({"case": case.name, **result})
        detail = result.get("reason") or result.get("error") or ""
        print(f"{result['class']:<9} {case.name:<42} {result.get('field', ''):<28} "
              f"{detail[:70]}", flush=True)
    counts = Counter(row["class"] for row in rows)
    print(f"\n{label}: {len(rows)} cases: " + ", ".join(
        f"{k} {counts[k]}" for k in ("specific", "vague", "crash", "accepted")))
    out = HERE / "results" / f"scenario_corpus-{label}.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"label": label, "root": str(args.root), "counts": counts,
                               "cases": rows}, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
