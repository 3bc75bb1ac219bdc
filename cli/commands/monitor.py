"""``tlfleet monitor SCENARIO TRAJECTORY.csv [--json]``: STL robustness of a recorded trajectory.

For every STL robot of the scenario, prints the robustness of each sub-task and of their conjunction
(min) with the standard min/max semantics (stl-funnel.md §3, §9 item 6), computed offline from the
CSV (``t,x1,y1,th1,x2,y2,th2,…``, robot ids ascending; architecture.md §6). ``--smooth`` uses the
LSE conjunction of eq. (3a) instead. A window with no sample is reported as +inf (G) or −inf (F).

A window the trace does not cover (it starts after a or ends before b) has no verdict: the
sub-task is marked ``covered: false`` in the JSON, a warning naming it goes to stderr, and
``--strict`` makes the command exit 3.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from tlfleet.agent.scenario import load_scenario
from tlfleet.agent.stl.monitor import evaluate_trajectory, read_trajectory_csv
from tlfleet.cli.arg_types import scenario_file

NAME = "monitor"
HELP = "STL robustness of a recorded trajectory"
EXAMPLES = (
    ("tlfleet monitor scenario2.toml runs/s2/trajectory.csv",
     "the STL robustness of every robot of a recorded Scenario 2 run"),
    ("tlfleet monitor scenario2.toml runs/s2/trajectory.csv --json --strict",
     "the same as JSON; exit 3 if the trace misses a window"),
)
EXIT_CODES = {0: "computed", 1: "an invalid scenario or trajectory file",
              3: "--strict and the trace does not cover a sub-task's window"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=scenario_file,
                        help="scenario TOML file or a bundled scenario's name")
    parser.add_argument("trajectory", help="trajectory CSV (t,x1,y1,th1,...)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--smooth", action="store_true",
                        help="LSE conjunction (eq. 3a) instead of the standard min")
    parser.add_argument("--strict", action="store_true",
                        help="exit 3 when the trace does not cover a sub-task's window")


def _number(value: float) -> float | str:
    return value if math.isfinite(value) else ("inf" if value > 0 else "-inf")


def evaluate(scenario_path: str, trajectory_path: str, smooth: bool = False) -> dict:
    """{robot id: {"subtasks": [{"task", "window", "robustness"}], "robustness": min}}."""
    return evaluate_trajectory(load_scenario(scenario_path), read_trajectory_csv(trajectory_path),
                               trajectory_path, smooth=smooth)


def run(args: argparse.Namespace) -> int:
    report = evaluate(args.scenario, args.trajectory, smooth=args.smooth)
    uncovered = [(rid, k, sub) for rid, entry in report.items()
                 for k, sub in enumerate(entry["subtasks"]) if not sub["covered"]]
    for rid, k, sub in uncovered:
        print(f"tlfleet monitor: warning: {args.trajectory} does not cover the window "
              f"[{sub['window'][0]:g}, {sub['window'][1]:g}] of robot {rid} sub-task {k + 1} "
              f"({sub['task']}): its robustness {_number(sub['robustness'])} is no verdict",
              file=sys.stderr)
    code = 3 if uncovered and args.strict else 0
    if args.json:
        print(json.dumps({
            "semantics": "smooth" if args.smooth else "standard",
            "robots": {str(rid): {"robustness": _number(entry["robustness"]),
                                  "subtasks": [{**sub, "robustness": _number(sub["robustness"])}
                                               for sub in entry["subtasks"]]}
                       for rid, entry in report.items()},
        }, indent=2))
        return code
    print(f"STL robustness ({'smooth' if args.smooth else 'standard'} semantics) of "
          f"{args.trajectory}")
    for rid, entry in report.items():
        print(f"robot {rid}: {entry['robustness']:+.4f}")
        for sub in entry["subtasks"]:
            print(f"    {sub['robustness']:+.4f}  {sub['task']}"
                  + ("" if sub["covered"] else "  (window not covered by the trace)"))
    return code
